//! The one harness of the integration tests, in the manner of ripgrep's `tests/util.rs`:
//!
//! - [`TestDir`]: a temporary folder per test (`mgmot_testkit`'s, shared with the simulator's
//!   tests), removed when the test passes, kept (and its path
//!   printed) when the test fails or `MGMOT_KEEP_TEST_DIRS=1` is set, to look at the configs,
//!   logs and stats a failed run left;
//! - [`mgmot`] and [`sim`]: command builders ([`TestCommand`]) for the two binaries, and
//!   [`Scenario`] for the simulator's scenario arguments;
//! - [`Proc`]: a running child process, killed and reaped when it is dropped, so that a test
//!   that panics leaves no process behind;
//! - [`run_config`]: `mgmot run` configurations as typed [`Config`] values, written as TOML by
//!   [`TestDir::write_config`];
//! - [`Relay`]: the UDP link between the simulator (autopilot) and `mgmot run`, recording what
//!   mgmot sends;
//! - [`read_truth`], [`distance_m`], [`track_time_ms`]: the simulator's ground truth and
//!   positions on the sea;
//! - [`missing_tool`]: the failure of a cross-check whose outside tool is not installed.
//!

mod relay;

pub use mgmot_testkit::{free_tcp_port, free_udp_port};
pub use relay::{Relay, Sent};

use mgmot::config::{Config, DetectorConfig, FramesConfig};
use std::ffi::OsStr;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Autopilot clock at sim time 0 (the scenarios' default `telemetry.boot_time_s`).
pub const BOOT_TIME_S: f64 = 120.0;

/// Metres per degree of latitude (spherical approximation; the distances in the tests are tens
/// of metres, where it is good to millimetres).
pub const M_PER_DEG: f64 = 111_320.0;

/// A test's temporary folder ([`mgmot_testkit::TestDir`]: kept when the test fails), with
/// the runtime's configurations written into it.
#[derive(Default)]
pub struct TestDir(mgmot_testkit::TestDir);

impl TestDir {
    /// A new, empty folder.
    pub fn new() -> TestDir {
        TestDir(mgmot_testkit::TestDir::new())
    }

    /// Writes `config` as TOML to `name` in the folder; its path.
    pub fn write_config(&self, name: &str, config: &Config) -> PathBuf {
        let text = toml::to_string(config).expect("a Config serializes to TOML");
        self.write(name, text)
    }

    /// `dets.json`: an empty COCO results file, for the replay detector of a run whose
    /// detections do not matter.
    pub fn empty_detections(&self) -> PathBuf {
        self.write("dets.json", "[]")
    }
}

impl std::ops::Deref for TestDir {
    type Target = mgmot_testkit::TestDir;

    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

/// The simulator binary: `$MGMOT_SIM_BIN`, or the one `cargo build -p mgmot-sim` builds here
/// in this test build's profile (a workspace member): `target/debug/mgmot-sim`, or
/// `target/release/mgmot-sim` under `cargo test --release`. Built once per test binary.
pub fn sim_bin() -> PathBuf {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(p) = std::env::var_os("MGMOT_SIM_BIN") {
            return PathBuf::from(p);
        }
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let release = !cfg!(debug_assertions);
        let mut build = Command::new(env!("CARGO"));
        build.args(["build", "-p", "mgmot-sim"]).current_dir(root);
        if release {
            build.arg("--release");
        }
        let status = build.status().expect("running cargo build -p mgmot-sim");
        assert!(status.success(), "cargo build -p mgmot-sim failed");
        root.join(if release {
            "target/release/mgmot-sim"
        } else {
            "target/debug/mgmot-sim"
        })
    })
    .clone()
}

/// A file of this repository.
pub fn repo_file(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// A copy of the repository's `model` in `dir`, as `name`, whose class `swimmer` is called
/// `swimmex` (same length: the protobuf stays valid), whatever the other classes.
pub fn model_with_swimmer_renamed(dir: &TestDir, model: &str, name: &str) -> PathBuf {
    let mut bytes = std::fs::read(repo_file(model)).unwrap();
    let at = bytes
        .windows(9)
        .position(|w| w == b"'swimmer'")
        .expect("the model names a swimmer class");
    bytes[at..at + 9].copy_from_slice(b"'swimmex'");
    dir.write(name, bytes)
}

/// The shipped example configuration, made true on this machine: the repository's model on
/// the tract backend instead of the installed model and ONNX Runtime library (which
/// `check-config` requires to exist). Written into `dir`.
pub fn example_config_here(dir: &TestDir) -> PathBuf {
    example_config_with_detector(dir, &repo_file("models/mgmot-det-int8.onnx"), "tract", None)
}

/// The shipped example with its `[detector]` lines `model`, `backend` and `ort_library` set as
/// given (`None`: the line left out), its `alternatives` left out (the installed fp32
/// model: one candidate, nothing timed at start) and its `tile_model` the repository's,
/// written into `dir` as `mgmot.toml`.
pub fn example_config_with_detector(
    dir: &TestDir,
    model: &Path,
    backend: &str,
    ort_library: Option<&Path>,
) -> PathBuf {
    let example = std::fs::read_to_string(repo_file("systemd/mgmot.example.toml"))
        .expect("reading systemd/mgmot.example.toml");
    let mut out = String::new();
    for line in example.lines() {
        if line.starts_with("model = ") {
            out += &format!("model = {:?}\n", model.display().to_string());
        } else if line.starts_with("backend = ") {
            out += &format!("backend = {backend:?}\n");
        } else if line.starts_with("alternatives = ") {
            continue;
        } else if line.starts_with("tile_model = ") {
            let tiles = repo_file("models/mgmot-det-tiles-int8.onnx");
            out += &format!("tile_model = {:?}\n", tiles.display().to_string());
        } else if line.starts_with("ort_library = ") {
            if let Some(lib) = ort_library {
                out += &format!("ort_library = {:?}\n", lib.display().to_string());
            }
        } else {
            out += line;
            out += "\n";
        }
    }
    dir.write("mgmot.toml", out)
}

/// The `mgmot` binary of this build.
pub fn mgmot() -> TestCommand {
    TestCommand::new(env!("CARGO_BIN_EXE_mgmot"))
}

/// The `mgmot` binary of this build, run so that file permissions bind it: as root (a
/// container, CI) through `capsh` without CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH, so that a
/// read-only folder or a socket without write permission is refused as it is to the service
/// user; as anyone else, as is.
pub fn mgmot_bound_by_permissions() -> TestCommand {
    let root = Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false);
    if !root {
        return mgmot();
    }
    if Command::new("capsh").arg("--help").output().is_err() {
        missing_tool("mgmot_bound_by_permissions", "capsh (libcap2-bin)");
    }
    let mut c = TestCommand::new("capsh");
    c.args([
        "--drop=cap_dac_override,cap_dac_read_search",
        "--",
        "-c",
        "exec \"$0\" \"$@\"",
        env!("CARGO_BIN_EXE_mgmot"),
    ]);
    c
}

/// The `mgmot-sim` binary ([`sim_bin`]).
pub fn sim() -> TestCommand {
    TestCommand::new(sim_bin())
}

/// A command to run, with stdin closed: to its end ([`output`](Self::output), [`ok`](Self::ok),
/// [`output_within`](Self::output_within)) or in the background as a [`Proc`]
/// ([`spawn`](Self::spawn), [`spawn_logged`](Self::spawn_logged)).
pub struct TestCommand {
    cmd: Command,
    stdout_set: bool,
}

impl TestCommand {
    pub fn new(program: impl AsRef<OsStr>) -> TestCommand {
        let mut cmd = Command::new(program);
        cmd.stdin(Stdio::null());
        TestCommand {
            cmd,
            stdout_set: false,
        }
    }

    pub fn arg(&mut self, arg: impl AsRef<OsStr>) -> &mut Self {
        self.cmd.arg(arg);
        self
    }

    pub fn args<I, S>(&mut self, args: I) -> &mut Self
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        self.cmd.args(args);
        self
    }

    pub fn env(&mut self, key: impl AsRef<OsStr>, value: impl AsRef<OsStr>) -> &mut Self {
        self.cmd.env(key, value);
        self
    }

    pub fn env_remove(&mut self, key: impl AsRef<OsStr>) -> &mut Self {
        self.cmd.env_remove(key);
        self
    }

    pub fn current_dir(&mut self, dir: impl AsRef<Path>) -> &mut Self {
        self.cmd.current_dir(dir);
        self
    }

    /// Where stdout goes (default: captured by the `output` calls, discarded by `spawn`).
    pub fn stdout(&mut self, stdout: impl Into<Stdio>) -> &mut Self {
        self.cmd.stdout(stdout);
        self.stdout_set = true;
        self
    }

    /// Runs it to the end, stdout and stderr captured.
    pub fn output(&mut self) -> Output {
        self.cmd
            .output()
            .unwrap_or_else(|e| panic!("starting {:?}: {e}", self.cmd))
    }

    /// Runs it to the end; a failure fails the test with its stderr.
    pub fn ok(&mut self) -> Output {
        let out = self.output();
        assert!(
            out.status.success(),
            "{:?}: {}\n{}",
            self.cmd,
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }

    /// Runs it to the end within `limit`, stdout (unless set) and stderr captured; past the
    /// limit it is killed and the test fails, naming `what`, so that a command that hangs (a
    /// read blocking on a FIFO, a run that never ends) fails the test instead of hanging it.
    pub fn output_within(&mut self, limit: Duration, what: &str) -> Output {
        if !self.stdout_set {
            self.cmd.stdout(Stdio::piped());
        }
        self.cmd.stderr(Stdio::piped());
        let mut child = self.start();
        let read_all = |pipe: Option<Box<dyn Read + Send>>| {
            std::thread::spawn(move || {
                let mut bytes = Vec::new();
                if let Some(mut pipe) = pipe {
                    let _ = pipe.read_to_end(&mut bytes);
                }
                bytes
            })
        };
        let stdout = read_all(
            child
                .stdout
                .take()
                .map(|p| Box::new(p) as Box<dyn Read + Send>),
        );
        let stderr = read_all(
            child
                .stderr
                .take()
                .map(|p| Box::new(p) as Box<dyn Read + Send>),
        );
        let mut p = Proc { child, log: None };
        let status = p
            .wait_within(limit)
            .unwrap_or_else(|| panic!("{what}: still running after {limit:?} (killed)"));
        Output {
            status,
            stdout: stdout.join().unwrap(),
            stderr: stderr.join().unwrap(),
        }
    }

    /// Starts it in the background, stdout (unless set) and stderr discarded.
    pub fn spawn(&mut self) -> Proc {
        if !self.stdout_set {
            self.cmd.stdout(Stdio::null());
        }
        self.cmd.stderr(Stdio::null());
        Proc {
            child: self.start(),
            log: None,
        }
    }

    /// Starts it in the background, stdout (unless set) discarded, stderr written to `log`
    /// ([`Proc::log`] reads it).
    pub fn spawn_logged(&mut self, log: impl AsRef<Path>) -> Proc {
        let log = log.as_ref();
        let file = std::fs::File::create(log).unwrap_or_else(|e| panic!("{}: {e}", log.display()));
        if !self.stdout_set {
            self.cmd.stdout(Stdio::null());
        }
        self.cmd.stderr(file);
        Proc {
            child: self.start(),
            log: Some(log.to_owned()),
        }
    }

    fn start(&mut self) -> Child {
        self.cmd
            .spawn()
            .unwrap_or_else(|e| panic!("starting {:?}: {e}", self.cmd))
    }
}

/// A child process, killed and reaped when dropped: when the test ends, passed or not.
pub struct Proc {
    child: Child,
    log: Option<PathBuf>,
}

impl Proc {
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Its exit status if it has ended.
    pub fn exited(&mut self) -> Option<ExitStatus> {
        self.child.try_wait().unwrap()
    }

    /// Waits up to `limit` for it to end; `None` if it is still running.
    pub fn wait_within(&mut self, limit: Duration) -> Option<ExitStatus> {
        let until = Instant::now() + limit;
        loop {
            if let Some(status) = self.exited() {
                return Some(status);
            }
            if Instant::now() >= until {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits up to `limit` for it to end; past that it is killed and the test fails.
    pub fn wait_or_fail(&mut self, limit: Duration) -> ExitStatus {
        self.wait_within(limit)
            .unwrap_or_else(|| panic!("process did not finish within {limit:?}; {}", self.log()))
    }

    /// Sends it SIGTERM, unless it has ended (and been reaped: its pid may be another's now).
    pub fn sigterm(&mut self) {
        use rustix::process::{kill_process, Pid, Signal};
        if self.exited().is_none() {
            kill_process(Pid::from_child(&self.child), Signal::TERM).expect("kill -TERM");
        }
    }

    /// SIGTERM, then waits up to `limit` for it to end; past that the test fails.
    pub fn stop(&mut self, limit: Duration) -> ExitStatus {
        self.sigterm();
        self.wait_within(limit)
            .unwrap_or_else(|| panic!("did not stop within {limit:?} of SIGTERM; {}", self.log()))
    }

    /// What it wrote on stderr so far, when started with [`TestCommand::spawn_logged`].
    pub fn log(&self) -> String {
        self.log
            .as_ref()
            .and_then(|p| std::fs::read_to_string(p).ok())
            .unwrap_or_default()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A simulator scenario: a shipped name or a scenario file, a length, and optionally a frame
/// size (smaller frames render and travel faster where the pixels are not looked at).
#[derive(Debug, Clone)]
pub struct Scenario {
    pub name: String,
    pub duration_s: f64,
    pub size_px: Option<(u32, u32)>,
    /// Which of the scenario's vehicles (`--vehicle K`); `None`: the first.
    pub vehicle: Option<usize>,
    /// Another seed than the scenario's (`--seed N`).
    pub seed: Option<u64>,
}

impl Scenario {
    pub fn new(name: impl Into<String>, duration_s: f64) -> Scenario {
        Scenario {
            name: name.into(),
            duration_s,
            size_px: None,
            vehicle: None,
            seed: None,
        }
    }

    pub fn seed(mut self, seed: Option<u64>) -> Scenario {
        self.seed = seed;
        self
    }

    pub fn vehicle(mut self, k: usize) -> Scenario {
        self.vehicle = Some(k);
        self
    }

    pub fn size(mut self, width: u32, height: u32) -> Scenario {
        self.size_px = Some((width, height));
        self
    }

    /// `--scenario NAME --duration-s S [--width W --height H]`.
    pub fn args(&self) -> Vec<String> {
        let mut a = vec![
            "--scenario".to_string(),
            self.name.clone(),
            "--duration-s".into(),
            self.duration_s.to_string(),
        ];
        if let Some((w, h)) = self.size_px {
            a.extend([
                "--width".into(),
                w.to_string(),
                "--height".into(),
                h.to_string(),
            ]);
        }
        if let Some(k) = self.vehicle {
            a.extend(["--vehicle".into(), k.to_string()]);
        }
        if let Some(seed) = self.seed {
            a.extend(["--seed".into(), seed.to_string()]);
        }
        a
    }

    /// `mgmot-sim detections` to `out` (COCO results; the ground truth goes beside it, in
    /// `<stem>_gt/`).
    pub fn detections(&self, out: &Path) {
        sim()
            .arg("detections")
            .args(self.args())
            .arg("-o")
            .arg(out)
            .ok();
    }

    /// `mgmot-sim run`, in real time or in lockstep, as the autopilot (`udpout` to
    /// `mavlink_port` on loopback) and the camera (the Unix socket `frames`).
    pub fn run(&self, realtime: bool, mavlink_port: u16, frames: &Path) -> TestCommand {
        let mut c = sim();
        c.arg("run")
            .args(self.args())
            .arg(if realtime { "--realtime" } else { "--lockstep" })
            .arg("--mavlink")
            .arg(format!("udpout:127.0.0.1:{mavlink_port}"))
            .arg("--frames")
            .arg(format!("unix:{}", frames.display()));
        c
    }
}

/// `mgmot run --config CONFIG [--stats-json STATS]`.
pub fn mgmot_run(config: &Path, stats: Option<&Path>) -> TestCommand {
    let mut c = mgmot();
    c.args(["run", "--config"]).arg(config);
    if let Some(stats) = stats {
        c.arg("--stats-json").arg(stats);
    }
    c
}

/// The keys without defaults; [`run_config`] sets them all.
const BASE_CONFIG: &str = r#"
[mavlink]
connection = "udpin:127.0.0.1:14550"
[frames]
source = "sim"
socket = "frames.sock"
[detector]
kind = "replay"
detections = "dets.json"
"#;

/// A `mgmot run` configuration: MAVLink on `connection`, frames from the simulator's Unix
/// socket `frames_socket`, detections replayed from `detections`, every other key at its
/// default. Tests change its fields and write it with [`TestDir::write_config`].
pub fn run_config(connection: &str, frames_socket: &Path, detections: &Path) -> Config {
    let mut c = Config::parse(BASE_CONFIG).expect("the harness's base configuration");
    c.mavlink.connection = connection.to_owned();
    let FramesConfig::Sim { socket, .. } = &mut c.frames else {
        unreachable!("the base reads frames from the simulator")
    };
    *socket = frames_socket.to_owned();
    let DetectorConfig::Replay {
        detections: replayed,
        ..
    } = &mut c.detector
    else {
        unreachable!("the base replays detections")
    };
    *replayed = detections.to_owned();
    c
}

/// One ground-truth object in one frame (a row of the simulator's `world.csv`).
#[derive(Debug, Clone)]
pub struct Truth {
    /// Sim time (ms).
    pub t_ms: i64,
    pub id: u64,
    pub class: String,
    pub lat: f64,
    pub lon: f64,
    /// True velocity north and east (m/s).
    pub vel_ne: (f64, f64),
}

/// The simulator's ground truth: `world.csv` of `mgmot-sim detections` (`<stem>_gt/`) or of
/// `mgmot-sim run --truth-out DIR`.
pub fn read_truth(world_csv: &Path) -> Vec<Truth> {
    let mut r = csv::Reader::from_path(world_csv)
        .unwrap_or_else(|e| panic!("{}: {e}", world_csv.display()));
    r.deserialize::<std::collections::HashMap<String, String>>()
        .map(|row| {
            let row = row.unwrap();
            let speed: f64 = row["speed_mps"].parse().unwrap();
            let heading = row["heading_deg"].parse::<f64>().unwrap().to_radians();
            Truth {
                vel_ne: (speed * heading.cos(), speed * heading.sin()),
                t_ms: (row["time_s"].parse::<f64>().unwrap() * 1000.0).round() as i64,
                id: row["id"].parse().unwrap(),
                class: row["class"].clone(),
                lat: row["lat_deg"].parse().unwrap(),
                lon: row["lon_deg"].parse().unwrap(),
            }
        })
        .collect()
}

/// Sim time (ms) of an autopilot timestamp (`time_usec` of MGMOT_TRACK).
pub fn track_time_ms(time_usec: u64) -> i64 {
    ((time_usec as f64 / 1e6 - BOOT_TIME_S) * 1000.0).round() as i64
}

/// Distance (m) between two (lat, lon) points in degrees, tens of metres apart: flat earth
/// at their mean latitude.
pub fn distance_m((lat1, lon1): (f64, f64), (lat2, lon2): (f64, f64)) -> f64 {
    let dn = (lat1 - lat2) * M_PER_DEG;
    let de = (lon1 - lon2) * M_PER_DEG * ((lat1 + lat2) / 2.0).to_radians().cos();
    dn.hypot(de)
}

/// Fails the test: the cross-check `test` needs an outside tool that is not there (`why`). A
/// missing tool never passes as a skip; scripts/test.sh provides them all.
pub fn missing_tool(test: &str, why: &str) -> ! {
    panic!(
        "{test} needs a tool that is missing: {why}. scripts/test.sh provides it: python \
         packages from scripts/requirements-test.txt in .venv (on PATH), ONNX Runtime through \
         ORT_DYLIB_PATH=\"$(scripts/detect_fetch_onnxruntime.sh)\""
    )
}

/// Fails the test through [`missing_tool`] unless `python3` imports every one of `modules`.
pub fn require_python(test: &str, modules: &[&str]) {
    let import = format!("import {}", modules.join(", "));
    match Command::new("python3").args(["-c", &import]).output() {
        Err(e) => missing_tool(test, &format!("python3 ({e})")),
        Ok(o) if !o.status.success() => missing_tool(
            test,
            &format!(
                "python3 cannot `{import}` ({})",
                String::from_utf8_lossy(&o.stderr).trim()
            ),
        ),
        Ok(_) => {}
    }
}

/// The SeaDronesSee subset in `../shared/data/seadronessee` (the shared folder beside the
/// repository): the path of `name` in it, which must exist.
pub fn shared_data(name: &str) -> String {
    let p = format!(
        "{}/../shared/data/seadronessee/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    assert!(
        Path::new(&p).exists(),
        "fixture missing: {p} (../shared must sit beside the repo)"
    );
    p
}
