//! Writes the seed corpus of mgmot's fuzz targets (`fuzz/corpus/<target>/seed-*`) from the
//! simulator and the test fixtures:
//!
//! ```sh
//! cargo run --release -p mgmot-fuzz-seeds -- fuzz/corpus
//! ```
//!
//! - `mavlink_frames`: MAVLink 2 frames of every telemetry stream the simulated autopilot
//!   sends, the operator commands mgmot obeys and the messages mgmot sends, unsigned and
//!   signed (with the targets' key, far-future timestamps so that replay protection keeps
//!   accepting them), alone and a few to a file;
//! - `mavlink_messages`: the same messages in that target's input layout (message id, header,
//!   payload);
//! - `sim_framing`: frame-stream frames rendered at small sizes;
//! - `seadronessee_json`: the simulator's SeaDronesSee JSON of a few frames of scenarios, and
//!   cuts of the real validation subset in `../shared` when it is there;
//! - `mot_txt`: the simulator's ground truth and detections of a few frames, and cuts of the
//!   TrackEval fixtures;
//! - `runtime_config`: the example configuration and variants of each frame source.
//!
//! Every file stays under 4 KB. Files of other names (regression inputs) are left alone;
//! `seed-*` files are rewritten.

use mgmot::frame::GeoFix;
use mgmot::mavlink::dialect::{
    MavCmd, MavMessage, COMMAND_INT_DATA, COMMAND_LONG_DATA, MOUNT_STATUS_DATA, TIMESYNC_DATA,
};
use mgmot::mavlink::{self as mav, AckResult, Severity};
use mgmot::report::TrackReport;
use mgmot_core::telemetry::AutopilotTimeUs;
use mgmot_sim::detections::{detect, mot_det_lines};
use mgmot_sim::framing::FrameHeader;
use mgmot_sim::output::{mot_gt_lines, SeaDronesSee};
use mgmot_sim::render::Renderer;
use mgmot_sim::scenario::Scenario;
use mgmot_sim::telemetry::{Autopilot, Stream};
use mgmot_sim::truth::{frame_truth, Optics};
use mgmot_sim::world::World;
// mgmot turns on mavlink-core's signing, which the simulator's `mavlink` re-exports.
use mavlink::{
    MAVLinkMessageRaw, MavHeader, MavlinkReader, MavlinkVersion, Message, SigningConfig,
    SigningData,
};
use std::path::{Path, PathBuf};

/// The fuzz targets' signing key (`fuzz/targets/mavlink.rs`).
const KEY: [u8; 32] = [0x5a; 32];
/// Largest seed.
const MAX_SEED: usize = 4096;

const SCENARIOS: [&str; 4] = [
    "leave_and_return",
    "swimmer_group",
    "gimbal_swings",
    "boats_crossing",
];

fn main() -> anyhow::Result<()> {
    let out = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("fuzz/corpus"));
    // The repository root (this package is fuzz/seeds/).
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut w = Writer::new(&out)?;
    mavlink(&mut w)?;
    framing(&mut w)?;
    annotations(&mut w, &root)?;
    mot(&mut w, &root)?;
    config(&mut w, &root)?;
    for (target, n, bytes) in &w.counts {
        println!("{target}: {n} seeds, {bytes} bytes");
    }
    Ok(())
}

/// Writes `seed-NNN` files per target, clearing the old seeds first.
struct Writer {
    out: PathBuf,
    counts: Vec<(String, usize, usize)>,
}

impl Writer {
    fn new(out: &Path) -> anyhow::Result<Self> {
        Ok(Self {
            out: out.to_owned(),
            counts: Vec::new(),
        })
    }

    fn put(&mut self, target: &str, data: &[u8]) -> anyhow::Result<()> {
        anyhow::ensure!(
            data.len() <= MAX_SEED,
            "{target}: a {} byte seed",
            data.len()
        );
        let dir = self.out.join(target);
        if !self.counts.iter().any(|(t, _, _)| t == target) {
            std::fs::create_dir_all(&dir)?;
            for e in std::fs::read_dir(&dir)? {
                let p = e?.path();
                if p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with("seed-"))
                {
                    std::fs::remove_file(p)?;
                }
            }
            self.counts.push((target.to_owned(), 0, 0));
        }
        let Some(c) = self.counts.iter_mut().find(|(t, _, _)| t == target) else {
            unreachable!()
        };
        std::fs::write(dir.join(format!("seed-{:03}", c.1)), data)?;
        c.1 += 1;
        c.2 += data.len();
        Ok(())
    }
}

fn world(name: &str, frames: u64, size: Option<(u32, u32)>) -> anyhow::Result<World> {
    let mut s = Scenario::load(name)?;
    if let Some((w, h)) = size {
        s.camera.width_px = w;
        s.camera.height_px = h;
    }
    s.duration_s = frames as f64 / s.camera.fps;
    let seed = s.seed;
    Ok(World::new(s, seed))
}

/// A MAVLink 2 frame of `msg`; signed frames carry a far-future timestamp `ts`.
fn frame(
    msg: &MavMessage,
    system_id: u8,
    component_id: u8,
    seq: u8,
    signed: Option<u64>,
) -> Vec<u8> {
    let header = MavHeader {
        system_id: system_id.into(),
        component_id,
        sequence: seq,
    };
    let signer = signed.map(|_| SigningData::from_config(SigningConfig::new(KEY, 1, true, false)));
    let mut bytes = Vec::new();
    mavlink::write_versioned_msg_signed(
        &mut bytes,
        MavlinkVersion::V2,
        header,
        msg,
        signer.as_ref(),
    )
    .expect("writing to a Vec");
    let Some(ts) = signed else {
        return bytes;
    };
    // Re-sign with a timestamp replay protection accepts for decades.
    let raw = MavlinkReader::new(&bytes[..])
        .read_raw_message::<MavMessage>(MavlinkVersion::V2)
        .expect("our own frame");
    let MAVLinkMessageRaw::V2(mut v2) = raw else {
        unreachable!("MAVLink 2")
    };
    v2.signature_timestamp_bytes_mut()
        .copy_from_slice(&ts.to_le_bytes()[..6]);
    let mut signature = [0u8; 6];
    v2.calculate_signature(&KEY, &mut signature);
    v2.signature_value_mut().copy_from_slice(&signature);
    v2.raw_bytes().to_vec()
}

/// The `mavlink_messages` target's input for `msg`.
fn message_input(
    msg: &MavMessage,
    system_id: u8,
    component_id: u8,
    seq: u8,
    sign: bool,
) -> Vec<u8> {
    let mut payload = [0u8; 255];
    let n = msg.ser(MavlinkVersion::V2, &mut payload);
    let mut out = msg.message_id().to_le_bytes()[..3].to_vec();
    out.extend([system_id, component_id, seq, u8::from(sign), 7]);
    out.extend(&payload[..n]);
    out
}

fn command_long(command: MavCmd, params: [f32; 7], target_component: u8) -> MavMessage {
    let [param1, param2, param3, param4, param5, param6, param7] = params;
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component,
        command,
        confirmation: 0,
        param1,
        param2,
        param3,
        param4,
        param5,
        param6,
        param7,
    })
}

fn mavlink(w: &mut Writer) -> anyhow::Result<()> {
    // (message, system, component)
    let mut messages: Vec<(MavMessage, u8, u8)> = Vec::new();
    for (k, name) in SCENARIOS.iter().enumerate() {
        let world = world(name, 60, None)?;
        let autopilot = Autopilot::new(&world)?;
        for stream in Stream::ALL {
            let t = 0.5 + k as f64 * 0.7;
            let component = match stream {
                Stream::GimbalDeviceAttitudeStatus => 154,
                _ => 1,
            };
            messages.push((autopilot.message(stream, t), 1, component));
        }
    }
    #[allow(deprecated)]
    let mount_status = MavMessage::MOUNT_STATUS(MOUNT_STATUS_DATA {
        pointing_a: -4500,
        pointing_b: 0,
        pointing_c: 1000,
        ..Default::default()
    });
    messages.push((mount_status, 1, 1));
    messages.push((
        MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 1_234_567_000,
            ts1: 987_654_321_000,
            ..Default::default()
        }),
        1,
        1,
    ));
    let ours = mav::COMPONENT_ID;
    let gcs = [
        command_long(
            MavCmd::MAV_CMD_CAMERA_TRACK_POINT,
            [0.25, 0.5, 0.05, 0.0, 0.0, 0.0, 0.0],
            ours,
        ),
        command_long(
            MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE,
            [0.1, 0.2, 0.3, 0.4, 0.0, 0.0, 0.0],
            0,
        ),
        command_long(MavCmd::MAV_CMD_CAMERA_STOP_TRACKING, [0.0; 7], ours),
        command_long(
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            [259.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ours,
        ),
        command_long(
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ours,
        ),
        MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            target_system: 1,
            target_component: ours,
            command: MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE,
            param1: 0.1,
            param2: 0.2,
            param3: 0.3,
            param4: 0.4,
            x: 0,
            ..Default::default()
        }),
    ];
    messages.extend(gcs.into_iter().map(|m| (m, 255, 190)));
    // What mgmot itself sends, for the other message ids.
    let report = TrackReport {
        time: AutopilotTimeUs(12_345_678),
        track_id: 7,
        merged_from_id: Some(3),
        class_id: 1,
        confidence: 0.8,
        bbox_norm: [0.4, 0.5, 0.05, 0.08],
        tracked: true,
        geo: Some(GeoFix {
            position: mgmot_core::geo::Geodetic::new(47.67, 9.26, 395.0)?,
            vel_n_mps: 0.3,
            vel_e_mps: 0.1,
            h_std_m: 2.5,
            ce95_m: 4.3,
        }),
        provisional: false,
    };
    messages.push((mav::heartbeat(), 1, ours));
    // A short text and a long one in chunks (id, chunk_seq).
    for text in [
        "mgmot: no telemetry",
        "mgmot: recording stopped: Input/output error (os error 5), the flight goes on",
    ] {
        let id = std::num::NonZeroU16::MIN;
        for m in mav::statustext(Severity::Warning, text, id) {
            messages.push((m, 1, ours));
        }
    }
    messages.push((mav::mgmot_track(&report), 1, ours));
    if let Some(m) = mav::target_absolute(&report) {
        messages.push((m, 1, ours));
    }
    messages.push((
        mav::command_ack(
            MavCmd::MAV_CMD_CAMERA_TRACK_POINT,
            AckResult::Accepted,
            255,
            190,
        ),
        1,
        ours,
    ));
    messages.push((mav::camera_information(1000, Some((1280, 720))), 1, ours));

    let mut ts = 1u64 << 46;
    let mut all_frames = Vec::new();
    for (k, (msg, sys, comp)) in messages.iter().enumerate() {
        let signed = k % 3 == 2;
        ts += 1;
        let f = frame(msg, *sys, *comp, k as u8, signed.then_some(ts));
        w.put("mavlink_frames", &f)?;
        w.put(
            "mavlink_messages",
            &message_input(msg, *sys, *comp, k as u8, signed),
        )?;
        all_frames.push(f);
    }
    // A few frames to a file, with noise between them, as on a serial link.
    for chunk in all_frames.chunks(6) {
        let mut bytes = Vec::new();
        for (k, f) in chunk.iter().enumerate() {
            bytes.extend(f);
            bytes.extend(&[0u8, 0x55, 0xfd][..k % 3]);
        }
        w.put("mavlink_frames", &bytes)?;
    }
    Ok(())
}

fn framing(w: &mut Writer) -> anyhow::Result<()> {
    for (k, (name, size)) in [
        ("leave_and_return", (16, 9)),
        ("swimmer_group", (8, 6)),
        ("gimbal_swings", (12, 7)),
        ("boats_crossing", (20, 12)),
        ("calm_baseline", (4, 2)),
        ("fast_drone", (1, 1)),
    ]
    .into_iter()
    .enumerate()
    {
        let world = world(name, 10, Some(size))?;
        let optics = Optics::new(&world.scenario)?;
        let renderer = Renderer::new(&world.scenario, world.seed);
        let mut stream = Vec::new();
        for index in 0..3u64 {
            let t = world.frame_time_s(index);
            let mut rgb = vec![0u8; renderer.frame_bytes()];
            renderer.render(&world, &optics, t, &mut rgb, true);
            let h = FrameHeader::rgb24(index, world.frame_stamp_us(t), size.0, size.1);
            let mut bytes = h.encode().to_vec();
            bytes.extend(&rgb);
            if index == 0 {
                w.put("sim_framing", &bytes)?;
            }
            stream.extend(bytes);
        }
        if stream.len() <= MAX_SEED {
            w.put("sim_framing", &stream)?;
        }
        // A header alone, and one cut in its payload.
        if k == 0 {
            w.put("sim_framing", &stream[..40])?;
            w.put("sim_framing", &stream[..60])?;
        }
    }
    // A 1280x720 and an 8K header without their payloads.
    w.put(
        "sim_framing",
        &FrameHeader::rgb24(0, 1_000_000, 1280, 720).encode(),
    )?;
    w.put(
        "sim_framing",
        &FrameHeader::rgb24(1, 2_000_000, 7680, 4320).encode(),
    )?;
    Ok(())
}

fn annotations(w: &mut Writer, root: &Path) -> anyhow::Result<()> {
    for name in SCENARIOS {
        let world = world(name, 30, None)?;
        let optics = Optics::new(&world.scenario)?;
        for (first, count) in [(0u64, 1u64), (10, 2), (20, 3)] {
            let mut ds = SeaDronesSee::new(&world);
            for index in first..first + count {
                let mut ft = frame_truth(&world, &optics, index);
                ft.boxes.truncate(3);
                ds.add_frame(&world, &optics, &ft, &format!("{:06}.png", index + 1));
            }
            let json = ds.to_json()?;
            if json.len() <= MAX_SEED {
                w.put("seadronessee_json", json.as_bytes())?;
            }
        }
    }
    // Cuts of the real validation subset: a few images of each video with their boxes.
    let real = root.join("../shared/data/seadronessee/val_subset_annotations.json");
    if let Ok(text) = std::fs::read_to_string(&real) {
        let v: serde_json::Value = serde_json::from_str(&text)?;
        let images = v["images"].as_array().cloned().unwrap_or_default();
        let annotations = v["annotations"].as_array().cloned().unwrap_or_default();
        for start in [0usize, 1, 60, 61, 120, 150] {
            for count in [1usize, 2, 3] {
                let Some(imgs) = images.get(start..start + count) else {
                    continue;
                };
                let ids: Vec<&serde_json::Value> = imgs.iter().map(|i| &i["id"]).collect();
                let anns: Vec<serde_json::Value> = annotations
                    .iter()
                    .filter(|a| ids.contains(&&a["image_id"]))
                    .take(4)
                    .cloned()
                    .collect();
                let mut cut = serde_json::Map::new();
                cut.insert("images".into(), imgs.to_vec().into());
                cut.insert("annotations".into(), anns.into());
                cut.insert("categories".into(), v["categories"].clone());
                let json = serde_json::to_string(&cut)?;
                if json.len() <= MAX_SEED && count < 3 || json.len() <= MAX_SEED / 2 {
                    w.put("seadronessee_json", json.as_bytes())?;
                }
            }
        }
    }
    Ok(())
}

fn mot(w: &mut Writer, root: &Path) -> anyhow::Result<()> {
    for name in SCENARIOS {
        let world = world(name, 20, None)?;
        let optics = Optics::new(&world.scenario)?;
        let (mut gt, mut det) = (String::new(), String::new());
        for index in 0..4 {
            let ft = frame_truth(&world, &optics, index);
            gt.push_str(&mot_gt_lines(&ft));
            det.push_str(&mot_det_lines(index, &detect(&world, &optics, &ft)));
        }
        for text in [gt, det] {
            w.put("mot_txt", cut_lines(&text, MAX_SEED / 2).as_bytes())?;
        }
    }
    // The TrackEval fixtures: the first lines of ground truth and results.
    let eval = root.join("tests/fixtures/eval");
    let mut files = Vec::new();
    for case in sorted(&eval)? {
        for side in ["gt", "pred"] {
            for f in sorted(&case.join(side)).unwrap_or_default() {
                let gt = f.join("gt/gt.txt");
                if gt.is_file() {
                    files.push(gt);
                } else if f.extension().is_some_and(|e| e == "txt") {
                    files.push(f);
                }
            }
        }
    }
    for f in files.iter().take(24) {
        let text = std::fs::read_to_string(f)?;
        w.put("mot_txt", cut_lines(&text, 1024).as_bytes())?;
    }
    Ok(())
}

/// Whole lines of `text`, at most `max` bytes.
fn cut_lines(text: &str, max: usize) -> String {
    let mut out = String::new();
    for line in text.split_inclusive('\n') {
        if out.len() + line.len() > max {
            break;
        }
        out.push_str(line);
    }
    out
}

fn sorted(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    v.sort();
    Ok(v)
}

fn config(w: &mut Writer, root: &Path) -> anyhow::Result<()> {
    let example = std::fs::read_to_string(root.join("systemd/mgmot.example.toml"))?;
    // The example without its comments fits a seed; with them, it is the documentation.
    let bare: String = example
        .lines()
        .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty())
        .map(|l| format!("{l}\n"))
        .collect();
    w.put("runtime_config", bare.as_bytes())?;
    let mavlink = "[mavlink]\nconnection = \"udpin:0.0.0.0:14550\"\n";
    let signed = "[mavlink]\nconnection = \"serial:/dev/ttyS0:921600\"\nsystem_id = 1\ncomponent_id = 191\n\
                  stream_rate_hz = 20.0\ntimesync_hz = 0.5\n[mavlink.signing]\n\
                  key_hex = \"000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f\"\nlink_id = 3\n";
    let frames = [
        "[frames]\nsource = \"sim\"\nsocket = \"/tmp/mgmot-sim.sock\"\n",
        "[frames]\nsource = \"sim\"\nsocket = \"/tmp/s.sock\"\nreconnect_initial_ms = 10\nreconnect_max_ms = 10\n",
        "[frames]\nsource = \"v4l2\"\ndevice = \"/dev/video0\"\npixel_format = \"MJPG\"\nwidth_px = 1280\nheight_px = 720\nfps = 30\nbuffers = 4\nframe_timeout_ms = 2000\n",
        "[frames]\nsource = \"images\"\ndirectory = \"frames\"\nfps = 2.5\nloop = true\n",
    ];
    let detectors = [
        "[detector]\nkind = \"replay\"\ndetections = \"dets.json\"\n",
        "[detector]\nkind = \"onnx\"\nmodel = \"models/mgmot-det-int8.onnx\"\nbackend = \"onnxruntime\"\n\
         ort_library = \"/opt/onnxruntime/libonnxruntime.so\"\nthreads = 2\nscore_threshold = 0.3\n\
         nms_iou = 0.6\nlarger_box_iou = 0.7\nmax_detections = 100\nclass_names = [\"swimmer\", \"boat\"]\n\
         tile = true\ntile_size_px = 640\ntile_overlap_px = 64\n",
    ];
    let extras = [
        "",
        "[telemetry]\nmax_pose_age_ms = 200.0\ncamera_latency_ms = 40.0\nwater_level_amsl_m = 395.0\nlost_after_ms = 2000.0\n",
        "[telemetry]\nfixed_mount_pitch_deg = -45.0\n[camera]\nhfov_deg = 82.1\n",
        "[geolocation]\nmax_range_m = 3000.0\n[geolocation.noise]\nattitude_std_deg = 1.0\naltitude_std_m = 2.0\npixel_std_px = 3.0\nhorizontal_position_std_m = 1.5\n",
        "[outputs]\ntrack_rate_hz = 5.0\nheartbeat_hz = 1.0\ncamera_tracking_hz = 5.0\ntarget_absolute = true\ntrack_point_radius = 0.05\n",
    ];
    for (k, f) in frames.iter().enumerate() {
        for (j, d) in detectors.iter().enumerate() {
            let m = if (k + j) % 2 == 0 { mavlink } else { signed };
            let e = extras[(k * 2 + j) % extras.len()];
            w.put("runtime_config", format!("{m}{f}{d}{e}").as_bytes())?;
        }
    }
    for e in &extras[1..] {
        w.put(
            "runtime_config",
            format!("{mavlink}{}{}{e}", frames[0], detectors[0]).as_bytes(),
        )?;
    }
    // Invalid ones: each fails validation on a different key.
    let udp = "connection = \"udpin:0.0.0.0:14550\"\n";
    for bad in [
        "[mavlink]\nconnection = \"serial:/dev/ttyS0:fast\"\n[telemetry]\nmax_pose_age_ms = -1\n"
            .to_string(),
        "[mavlink]\nconnection = \"udpin:0.0.0.0:0\"\nsystem_id = 0\n".to_string(),
        format!("[mavlink]\n{udp}[outputs]\nheartbeat_hz = 0.0\ntrack_point_radius = 2.0\n"),
        "[mavlink]\nconnection = \"udpin:0.0.0.0:1\"\nrate = 3\n".to_string(),
    ] {
        w.put(
            "runtime_config",
            format!("{bad}{}{}", frames[2], detectors[1]).as_bytes(),
        )?;
    }
    Ok(())
}
