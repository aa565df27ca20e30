//! The configuration's tests: the TOML layer (defaults, unknown keys, the example file) and the
//! settings layer (typed values, every problem under its dotted key).

use super::mavlink::default_signing_state_file;
use super::*;
use crate::detect::BackendKind;
use std::time::Duration;

const EXAMPLE: &str = include_str!("../../systemd/mgmot.example.toml");

const MINIMAL: &str = r#"
[mavlink]
connection = "udpin:0.0.0.0:14550"
[frames]
source = "sim"
socket = "/tmp/mgmot-sim.sock"
[detector]
kind = "replay"
detections = "dets.json"
"#;

/// The dotted keys of every problem `validate` finds in `text` (which must parse and be
/// invalid).
fn problem_keys(text: &str) -> Vec<String> {
    Config::parse(text)
        .unwrap()
        .validate()
        .unwrap_err()
        .into_iter()
        .map(|p| p.key)
        .collect()
}

const ONNX: &str = r#"
[mavlink]
connection = "udpin:0.0.0.0:14550"
[frames]
source = "sim"
socket = "/tmp/mgmot-sim.sock"
[detector]
kind = "onnx"
model = "models/mgmot-det-int8.onnx"
ort_library = "/opt/onnxruntime/libonnxruntime.so"
class_names = ["swimmer", "boat"]
"#;

#[test]
fn example_is_valid() {
    let c = Config::parse(EXAMPLE).unwrap();
    c.validate().unwrap();
}

/// Every key the configuration has (defaults included) is written in the example, so the
/// example documents all of them.
#[test]
fn example_documents_every_key() {
    example_documents_every_key_of(MINIMAL);
    example_documents_every_key_of(ONNX);
}

fn example_documents_every_key_of(config: &str) {
    let mut c = Config::parse(config).unwrap();
    c.mavlink.signing = Some(SigningConfig {
        key_hex: "00".repeat(32),
        link_id: 0,
        state_file: default_signing_state_file(),
        accept_unsigned_telemetry: true,
    });
    c.mavlink.udp_peer = Some(([127, 0, 0, 1], 14555).into());
    c.telemetry.water_level_amsl_m = Some(0.0);
    c.telemetry.fixed_mount_pitch_deg = Some(0.0);
    // Through text: the tracker's per-class table has integer keys, which toml::Value lacks.
    let value: toml::Value = toml::from_str(&toml::to_string(&c).unwrap()).unwrap();
    let mut missing = Vec::new();
    fn walk(v: &toml::Value, prefix: &str, example: &str, missing: &mut Vec<String>) {
        if let toml::Value::Table(t) = v {
            for (k, v) in t {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                let as_key = format!("{k} =");
                let as_table = format!("[{key}]");
                let as_parent = format!("[{key}.");
                if !example.contains(&as_key)
                    && !example.contains(&as_table)
                    && !example.contains(&as_parent)
                {
                    missing.push(key.clone());
                }
                walk(v, &key, example, missing);
            }
        }
    }
    walk(&value, "", EXAMPLE, &mut missing);
    assert!(
        missing.is_empty(),
        "keys not in the example config: {missing:?}"
    );
}

#[test]
fn minimal_takes_defaults() {
    let c = Config::parse(MINIMAL).unwrap();
    c.validate().unwrap();
    assert_eq!(c.mavlink.component_id, 191);
    assert_eq!(c.telemetry.max_pose_age_ms, 200.0);
}

#[test]
fn unknown_key_is_named_with_its_line() {
    let text = MINIMAL.replace("[mavlink]", "[mavlink]\nconection = \"x\"");
    let e = Config::parse(&text).unwrap_err();
    assert!(e.contains("conection"), "{e}");
    assert!(e.contains("line 3") || e.contains("3 |"), "{e}");
}

#[test]
fn invalid_values_name_their_keys() {
    let text = MINIMAL
        .replace("udpin:0.0.0.0:14550", "udp:nowhere")
        .replace(
            "[frames]",
            "[outputs]\ntrack_rate_hz = 0\ncamera_tracking_hz = -1\ntrack_point_radius = 2\n\
             [mavlink.signing]\nkey_hex = \"abc\"\n[frames]",
        );
    let keys = problem_keys(&text);
    assert_eq!(
        keys,
        [
            "mavlink.connection",
            "mavlink.signing.key_hex",
            "outputs.track_rate_hz",
            "outputs.camera_tracking_hz",
            "outputs.track_point_radius"
        ]
    );
}

#[test]
fn frame_sources_parse_with_defaults_and_name_bad_keys() {
    let images = MINIMAL.replace(
        "source = \"sim\"\nsocket = \"/tmp/mgmot-sim.sock\"",
        "source = \"images\"\ndirectory = \"/data/img1\"\nfps = 10.0\nloop = true",
    );
    let c = Config::parse(&images).unwrap();
    c.validate().unwrap();
    assert_eq!(
        c.frames,
        FramesConfig::Images {
            directory: "/data/img1".into(),
            fps: 10.0,
            looping: true
        }
    );
    let v4l2 = MINIMAL.replace(
        "source = \"sim\"\nsocket = \"/tmp/mgmot-sim.sock\"",
        "source = \"v4l2\"\ndevice = \"/dev/video0\"\npixel_format = \"NV12\"\n\
         width_px = 1280\nheight_px = 720\nfps = 30",
    );
    let c = Config::parse(&v4l2).unwrap();
    c.validate().unwrap();
    let FramesConfig::V4l2 {
        buffers,
        frame_timeout_ms,
        reconnect_initial_ms,
        reconnect_max_ms,
        ..
    } = c.frames
    else {
        panic!("{:?}", c.frames)
    };
    assert_eq!(
        (
            buffers,
            frame_timeout_ms,
            reconnect_initial_ms,
            reconnect_max_ms
        ),
        (4, 2000, 1000, 5000)
    );
    let bad = v4l2
        .replace("NV12", "RGB3")
        .replace("fps = 30", "fps = 30\nbuffers = 1\nreconnect_max_ms = 10");
    let keys = problem_keys(&bad);
    assert_eq!(
        keys,
        [
            "frames.pixel_format",
            "frames.buffers",
            "frames.reconnect_max_ms"
        ]
    );
    let e = Config::parse(&images.replace("loop = true", "looping = true")).unwrap_err();
    assert!(e.contains("looping"), "{e}");
}

#[test]
fn onnx_detector_defaults_and_settings() {
    let c = Config::parse(ONNX).unwrap();
    c.validate().unwrap();
    let d = onnx_settings(&c);
    assert_eq!(d.model_path, Path::new("models/mgmot-det-int8.onnx"));
    assert_eq!(d.backend.kind, BackendKind::Tract);
    assert_eq!(
        d.backend.ort_dylib_path.as_deref(),
        Some(Path::new("/opt/onnxruntime/libonnxruntime.so"))
    );
    assert_eq!(d.threads, 2);
    assert_eq!(d.score_threshold, 0.25);
    assert_eq!(d.larger_box_iou, Some(0.7));
    assert_eq!(d.class_names.as_deref().map(<[String]>::len), Some(2));
    let off = Config::parse(&ONNX.replace(
        "kind = \"onnx\"",
        "kind = \"onnx\"\nbackend = \"onnxruntime\"\nlarger_box_iou = 1.0",
    ))
    .unwrap();
    let d = onnx_settings(&off);
    assert_eq!(d.backend.kind, BackendKind::OnnxRuntime);
    assert_eq!(d.larger_box_iou, None);
}

/// `backend = "auto"` is the default; `alternatives` are listed model files, handed to the
/// selection with the backend asked for.
#[test]
fn onnx_detector_backend_auto_and_alternatives() {
    use crate::detect::BackendChoice;
    let validated = |text: &str| match Config::parse(text).unwrap().validate().unwrap().detector {
        DetectorSettings::Onnx(o) => o,
        other => panic!("not the ONNX detector: {other:?}"),
    };
    let o = validated(ONNX);
    assert_eq!(o.backend, BackendChoice::Auto);
    assert!(o.alternatives.is_empty());
    // Until auto chooses, the settings run the main model on tract.
    assert_eq!(o.detector.backend.kind, BackendKind::Tract);
    let with = |lines: &str| ONNX.replace("kind = \"onnx\"", &format!("kind = \"onnx\"\n{lines}"));
    let o = validated(&with(
        "backend = \"auto\"\nalternatives = [\"models/mgmot-det-fp32.onnx\", \"b.onnx\"]",
    ));
    assert_eq!(o.backend, BackendChoice::Auto);
    assert_eq!(
        o.alternatives,
        [
            PathBuf::from("models/mgmot-det-fp32.onnx"),
            PathBuf::from("b.onnx")
        ]
    );
    for (text, choice, kind) in [
        ("tract", BackendChoice::Tract, BackendKind::Tract),
        (
            "onnxruntime",
            BackendChoice::OnnxRuntime,
            BackendKind::OnnxRuntime,
        ),
    ] {
        let o = validated(&with(&format!("backend = {text:?}")));
        assert_eq!((o.backend, o.detector.backend.kind), (choice, kind));
        assert_eq!(OnnxSettings::fixed(o.detector.clone()), o);
    }
    assert_eq!(
        problem_keys(&with("alternatives = [\"\"]")),
        ["detector.alternatives"]
    );
    // The key round-trips (the flight record writes the configuration as it took effect).
    let c = Config::parse(&with("alternatives = [\"b.onnx\"]")).unwrap();
    let again = Config::parse(&toml::to_string(&c).unwrap()).unwrap();
    assert_eq!(again.detector, c.detector);
}

/// `model` with the class name `from` (quoted, as in the `names` metadata) renamed to `to`,
/// of the same length so that the protobuf stays valid, written to `out`.
fn with_class_renamed(model: &Path, from: &str, to: &str, out: &Path) {
    assert_eq!(from.len(), to.len());
    let (from, to) = (format!("'{from}'"), format!("'{to}'"));
    let mut bytes = std::fs::read(model).unwrap();
    let at = bytes
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap();
    bytes[at..at + to.len()].copy_from_slice(to.as_bytes());
    std::fs::write(out, bytes).unwrap();
}

/// What `check_files` finds in the configuration `text` (which must validate), as
/// "key: problem" lines.
fn file_problems(text: &str) -> Vec<String> {
    let settings = Config::parse(text).unwrap().validate().unwrap();
    let mut p = super::problems::Problems::default();
    settings.detector.check_files(&mut p);
    if p.is_empty() {
        return Vec::new();
    }
    p.into_vec()
        .into_iter()
        .map(|p| format!("{}: {}", p.key, p.problem))
        .collect()
}

/// `check_files` (what `mgmot check-config` adds): a missing alternative, and one with other
/// classes or another input size, are problems under `detector.alternatives`; under `auto` a
/// configured ONNX Runtime library must exist, one from `ORT_DYLIB_PATH` need not.
#[test]
fn onnx_detector_alternatives_are_checked_on_disk() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let fp32 = repo.join("models/mgmot-det-fp32.onnx");
    let int8 = repo.join("models/mgmot-det-int8.onnx");
    let renamed = dir.path().join("renamed.onnx");
    with_class_renamed(&fp32, "swimmer", "swimmex", &renamed);
    let missing = dir.path().join("gone.onnx");
    let problems = |backend: &str, alternatives: &[&Path], ort: Option<&Path>| {
        let mut text = ONNX
            .replace("models/mgmot-det-int8.onnx", &int8.display().to_string())
            .replace(
                "kind = \"onnx\"",
                &format!(
                    "kind = \"onnx\"\nbackend = {backend:?}\nalternatives = {:?}",
                    alternatives
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect::<Vec<_>>()
                ),
            );
        text = match ort {
            Some(lib) => text.replace(
                "/opt/onnxruntime/libonnxruntime.so",
                &lib.display().to_string(),
            ),
            None => text.replace("ort_library = \"/opt/onnxruntime/libonnxruntime.so\"\n", ""),
        };
        file_problems(&text)
    };
    assert_eq!(problems("auto", &[&fp32], None), Vec::<String>::new());
    let found = problems("tract", &[&fp32, &missing, &renamed], None);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        found[0].starts_with("detector.alternatives: ") && found[0].contains("gone.onnx"),
        "{found:?}"
    );
    assert!(
        found[1].starts_with("detector.alternatives: ")
            && found[1].contains("renamed.onnx")
            && found[1].contains("class names"),
        "{found:?}"
    );
    // A configured library that is not there is a problem under auto too.
    let found = problems("auto", &[], Some(&missing));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("detector.ort_library: "), "{found:?}");
}

/// `tile_model` reaches the detector's settings and round-trips; an empty one is a problem;
/// `check_files` wants it readable, with the main model's classes and input size.
#[test]
fn onnx_detector_tile_model() {
    let with = |lines: &str| ONNX.replace("kind = \"onnx\"", &format!("kind = \"onnx\"\n{lines}"));
    let c = Config::parse(ONNX).unwrap();
    assert_eq!(onnx_settings(&c).tile_model, None);
    let text = with("tile = \"auto\"\ntile_model = \"models/mgmot-det-tiles-int8.onnx\"");
    let c = Config::parse(&text).unwrap();
    assert_eq!(
        onnx_settings(&c).tile_model,
        Some(PathBuf::from("models/mgmot-det-tiles-int8.onnx"))
    );
    let again = Config::parse(&toml::to_string(&c).unwrap()).unwrap();
    assert_eq!(again.detector, c.detector);
    assert_eq!(
        problem_keys(&with("tile_model = \"\"")),
        ["detector.tile_model"]
    );

    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let int8 = repo.join("models/mgmot-det-int8.onnx");
    let tiles = repo.join("models/mgmot-det-tiles-int8.onnx");
    let renamed = dir.path().join("renamed.onnx");
    with_class_renamed(&tiles, "boat", "boot", &renamed);
    let problems = |tile_model: &Path| {
        let text = ONNX
            .replace("models/mgmot-det-int8.onnx", &int8.display().to_string())
            .replace("class_names = [\"swimmer\", \"boat\"]\n", "")
            .replace(
                "kind = \"onnx\"",
                &format!(
                    "kind = \"onnx\"\nbackend = \"tract\"\ntile = true\ntile_model = {:?}",
                    tile_model.display().to_string()
                ),
            );
        file_problems(&text)
    };
    assert_eq!(problems(&tiles), Vec::<String>::new());
    let found = problems(&dir.path().join("gone.onnx"));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].starts_with("detector.tile_model: ") && found[0].contains("gone.onnx"),
        "{found:?}"
    );
    let found = problems(&renamed);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].starts_with("detector.tile_model: ")
            && found[0].contains("renamed.onnx")
            && found[0].contains("class names"),
        "{found:?}"
    );
}

fn onnx_settings(c: &Config) -> crate::detect::DetectorConfig {
    match &c.detector {
        DetectorConfig::Onnx(o) => o.settings(),
        other => panic!("not the ONNX detector: {other:?}"),
    }
}

#[test]
fn onnx_detector_tiling_keys() {
    let c = Config::parse(&ONNX.replace(
        "kind = \"onnx\"",
        "kind = \"onnx\"\ntile = true\ntile_size_px = 640\ntile_overlap_px = 96",
    ))
    .unwrap();
    c.validate().unwrap();
    let t = onnx_settings(&c).tiling.unwrap();
    assert_eq!(
        (t.tile_px, t.overlap_px, t.include_full_frame),
        (Some(640), 96, true)
    );
    assert_eq!(onnx_settings(&Config::parse(ONNX).unwrap()).tiling, None);
    let keys = problem_keys(&ONNX.replace(
        "kind = \"onnx\"",
        "kind = \"onnx\"\ntile = true\ntile_size_px = 100\ntile_overlap_px = 100",
    ));
    assert_eq!(keys, ["detector.tile_overlap_px"]);
}

#[test]
fn onnx_detector_tile_auto_sets_a_frame_budget() {
    let auto = |extra: &str| {
        Config::parse(&ONNX.replace(
            "kind = \"onnx\"",
            &format!("kind = \"onnx\"\ntile = \"auto\"{extra}"),
        ))
    };
    let c = auto("").unwrap();
    c.validate().unwrap();
    let t = onnx_settings(&c).tiling.unwrap();
    // 15 frames/s by default: 66.667 ms.
    assert_eq!(t.frame_budget_us, Some(66_667));
    let c = auto("\ntile_min_fps = 10").unwrap();
    assert_eq!(
        onnx_settings(&c).tiling.unwrap().frame_budget_us,
        Some(100_000)
    );
    // `true` tiles every frame, with no budget.
    let on =
        Config::parse(&ONNX.replace("kind = \"onnx\"", "kind = \"onnx\"\ntile = true")).unwrap();
    assert_eq!(onnx_settings(&on).tiling.unwrap().frame_budget_us, None);
    assert_eq!(
        problem_keys(&ONNX.replace(
            "kind = \"onnx\"",
            "kind = \"onnx\"\ntile = \"auto\"\ntile_min_fps = 0"
        )),
        ["detector.tile_min_fps"]
    );
    // Any other word is refused when parsing, naming what is accepted.
    let e = Config::parse(&ONNX.replace("kind = \"onnx\"", "kind = \"onnx\"\ntile = \"yes\""))
        .unwrap_err()
        .to_string();
    assert!(e.contains("true, false or \"auto\""), "{e}");
}

#[test]
fn onnx_detector_problems_name_their_keys() {
    let text = ONNX
        .replace(
            "kind = \"onnx\"",
            "kind = \"onnx\"\nthreads = 0\nscore_threshold = 1.5\nnms_iou = -0.1\n\
         larger_box_iou = 0.0\nmax_detections = 0",
        )
        .replace("[\"swimmer\", \"boat\"]", "[\"swimmer\", \" \"]");
    let keys = problem_keys(&text);
    assert_eq!(
        keys,
        [
            "detector.threads",
            "detector.score_threshold",
            "detector.nms_iou",
            "detector.larger_box_iou",
            "detector.max_detections",
            "detector.class_names"
        ]
    );
    let e = Config::parse(&ONNX.replace("kind = \"onnx\"", "kind = \"onnx\"\nbackend = \"cuda\""))
        .unwrap_err();
    // The detector table is parsed as a whole (internally tagged): the error points at the
    // `[detector]` line and names the bad value and the accepted ones.
    assert!(
        e.contains("cuda") && e.contains("[detector]") && e.contains("onnxruntime"),
        "{e}"
    );
}

/// Issue "Hardening" item 10: numbers that validated before and then broke `mgmot run`
/// (a panic at start, a panicking task, 110,000 heartbeats in 20 s) are refused with their
/// key named.
#[test]
fn out_of_range_numbers_are_refused_with_their_key() {
    for (key, section, value) in [
        ("heartbeat_hz", "outputs", "1e-300"),
        ("heartbeat_hz", "outputs", "1e300"),
        ("heartbeat_hz", "outputs", "2e9"),
        ("heartbeat_hz", "outputs", "nan"),
        ("track_rate_hz", "outputs", "inf"),
        ("camera_tracking_hz", "outputs", "1e9"),
        ("timesync_hz", "mavlink", "1e12"),
        ("max_range_m", "geolocation", "1e308"),
        ("lost_after_ms", "telemetry", "1e300"),
        ("max_pose_age_ms", "telemetry", "-1"),
    ] {
        let text = if section == "mavlink" {
            MINIMAL.replace("[mavlink]\n", &format!("[mavlink]\n{key} = {value}\n"))
        } else {
            format!("{MINIMAL}\n[{section}]\n{key} = {value}\n")
        };
        let c = Config::parse(&text).unwrap();
        let problems = c.validate().unwrap_err();
        assert!(
            problems.iter().any(|p| p.key == format!("{section}.{key}")),
            "{section}.{key} = {value}: {problems:?}"
        );
    }
    let mut c = Config::parse(MINIMAL).unwrap();
    c.outputs.heartbeat_hz = 1.0;
    c.validate().unwrap();
}

#[test]
fn signing_key_hex() {
    let s = SigningConfig {
        key_hex: "0f".repeat(32),
        link_id: 1,
        state_file: default_signing_state_file(),
        accept_unsigned_telemetry: true,
    };
    assert_eq!(s.key(), Some([0x0f; 32]));
    let bad = SigningConfig {
        key_hex: "zz".repeat(32),
        link_id: 1,
        state_file: default_signing_state_file(),
        accept_unsigned_telemetry: true,
    };
    assert_eq!(bad.key(), None);
}

const V4L2_ONNX: &str = r#"
[mavlink]
connection = "udpin:0.0.0.0:14550"
timesync_hz = 4
[mavlink.signing]
key_hex = "0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f0f"
[frames]
source = "v4l2"
device = "/dev/video0"
pixel_format = "NV12"
width_px = 1280
height_px = 720
fps = 30
[detector]
kind = "onnx"
model = "models/mgmot-det-int8.onnx"
"#;

/// The settings layer holds what the consumers use, parsed once: the pixel format, durations,
/// periods, the key bytes, the detector's settings.
#[test]
fn settings_are_typed() {
    let c = Config::parse(V4L2_ONNX).unwrap();
    let s = c.validate().unwrap();
    let FrameSettings::V4l2 { camera, reconnect } = &s.frames else {
        panic!("{:?}", s.frames)
    };
    assert_eq!(camera.pixel_format, crate::camera::PixelFormat::Nv12);
    assert_eq!(
        (camera.width_px, camera.height_px, camera.fps),
        (1280, 720, 30)
    );
    assert_eq!(
        (camera.buffers, camera.frame_timeout),
        (4, Duration::from_secs(2))
    );
    assert_eq!(
        *reconnect,
        ReconnectDelays {
            initial: Duration::from_secs(1),
            max: Duration::from_secs(5)
        }
    );
    assert_eq!(s.mavlink.timesync_every, Some(Duration::from_millis(250)));
    assert_eq!(s.mavlink.signing.as_ref().map(|k| k.key), Some([0x0f; 32]));
    assert_eq!(s.telemetry.max_pose_age, Duration::from_millis(200));
    assert_eq!(s.telemetry.lost_after, Duration::from_secs(2));
    assert_eq!(s.outputs.track_every, Duration::from_millis(500));
    assert_eq!(s.outputs.heartbeat_every, Duration::from_secs(1));
    assert_eq!(s.outputs.camera_tracking_every, Duration::from_millis(200));
    assert_eq!(s.camera.hfov_deg, 70.0);
    assert_eq!(s.geolocation.max_range_m, DEFAULT_MAX_RANGE_M);
    let DetectorConfig::Onnx(onnx) = &c.detector else {
        panic!("{:?}", c.detector)
    };
    assert_eq!(
        s.detector,
        DetectorSettings::Onnx(OnnxSettings {
            detector: onnx.settings(),
            backend: onnx.backend,
            alternatives: onnx.alternatives.clone(),
        })
    );
    let off = Config::parse(&V4L2_ONNX.replace("timesync_hz = 4", "timesync_hz = 0")).unwrap();
    assert_eq!(off.validate().unwrap().mavlink.timesync_every, None);
}

/// One mistake in every section: validation does not stop at the first, and each problem
/// names its dotted key, in section order.
#[test]
fn every_problem_of_every_section_is_collected() {
    let text = V4L2_ONNX
        .replace("timesync_hz = 4", "timesync_hz = 4\nsystem_id = 0")
        .replace("0f0f0f0f0f0f0f0f", "0f")
        .replace("NV12", "H264")
        .replace(
            "fps = 30",
            "fps = 30\nbuffers = 1\nreconnect_initial_ms = 0",
        )
        .replace("kind = \"onnx\"", "kind = \"onnx\"\nthreads = 0")
        + "[telemetry]\nlost_after_ms = 0\nfixed_mount_pitch_deg = 91\n\
           [camera]\nhfov_deg = 180\n\
           [geolocation]\nmax_range_m = 0\n\
           [geolocation.noise]\npixel_std_px = -1\n\
           [outputs]\nheartbeat_hz = 0\ntrack_point_radius = -0.5\n";
    let problems = Config::parse(&text).unwrap().validate().unwrap_err();
    let keys: Vec<&str> = problems.iter().map(|p| p.key.as_str()).collect();
    assert_eq!(
        keys,
        [
            "mavlink.system_id",
            "mavlink.signing.key_hex",
            "telemetry.lost_after_ms",
            "telemetry.fixed_mount_pitch_deg",
            "frames.pixel_format",
            "frames.buffers",
            "frames.reconnect_initial_ms",
            "detector.threads",
            "camera.hfov_deg",
            "geolocation.max_range_m",
            "geolocation.noise.pixel_std_px",
            "outputs.heartbeat_hz",
            "outputs.track_point_radius",
        ]
    );
    assert_eq!(
        problems[2].to_string(),
        "`telemetry.lost_after_ms`: must be a number in (0, 3600000], got 0"
    );
}

#[test]
fn tracker_problems_are_collected_with_the_rest() {
    let mut c = Config::parse(MINIMAL).unwrap();
    c.camera.hfov_deg = 0.0;
    c.tracker.baseline.track_low_thresh = 2.0;
    let keys: Vec<String> = c
        .validate()
        .unwrap_err()
        .into_iter()
        .map(|p| p.key)
        .collect();
    assert_eq!(keys, ["camera.hfov_deg", "tracker"]);
}

/// The frames section validates alone too (the pipeline's capture start, which holds the
/// configuration), with the same problems.
#[test]
fn frame_settings_alone() {
    let c = Config::parse(V4L2_ONNX).unwrap();
    assert_eq!(Ok(c.validate().unwrap().frames), c.frames.settings());
    let bad = Config::parse(&V4L2_ONNX.replace("width_px = 1280", "width_px = 0")).unwrap();
    let keys: Vec<String> = bad
        .frames
        .settings()
        .unwrap_err()
        .into_iter()
        .map(|p| p.key)
        .collect();
    assert_eq!(keys, ["frames.width_px"]);
}

#[test]
fn frame_sources_print_as_check_config_shows_them() {
    let v4l2 = Config::parse(V4L2_ONNX).unwrap().validate().unwrap();
    assert_eq!(
        v4l2.frames.to_string(),
        "v4l2 /dev/video0 NV12 1280x720 @ 30 fps"
    );
    let sim = Config::parse(MINIMAL).unwrap().validate().unwrap();
    assert_eq!(
        sim.frames.to_string(),
        "simulator socket /tmp/mgmot-sim.sock"
    );
}

#[test]
fn recording_is_off_by_default_and_its_problems_name_their_keys() {
    let off = Config::parse(MINIMAL).unwrap().validate().unwrap();
    assert_eq!(off.recording, None);
    let on = Config::parse(&format!(
        "{MINIMAL}[recording]\ndir = \"/var/lib/mgmot/flights\"\n"
    ))
    .unwrap()
    .validate()
    .unwrap()
    .recording
    .unwrap();
    assert_eq!(on.max_total_bytes, Some(4096 << 20));
    assert_eq!(on.keyframe_every, Some(Duration::from_secs(10)));
    let bad = format!(
        "{MINIMAL}[recording]\ndir = \"\"\nmax_total_mb = 3\nkeyframe_every_s = 0.1\nkeyframe_width_px = 10\nqueue = 1\n"
    );
    assert_eq!(
        problem_keys(&bad),
        [
            "recording.keyframe_every_s",
            "recording.keyframe_width_px",
            "recording.queue",
            "recording.max_total_mb",
            "recording.dir"
        ]
    );
}
