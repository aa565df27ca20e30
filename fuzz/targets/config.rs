//! The runtime configuration: `Config::parse` then `validate`, and what `mgmot check-config`
//! and `mgmot run` do with a configuration that validated.

use mgmot::config::{Config, DetectorConfig, FramesConfig};
use std::time::Duration;

/// `data` as the text of a configuration file (`Config::load` refuses invalid UTF-8 first).
pub fn toml(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(config) = Config::parse(text) else {
        return;
    };
    match config.validate() {
        Err(problems) => {
            assert!(!problems.is_empty(), "an empty list of problems");
            for p in &problems {
                // Each problem names its key, as the user sees it.
                assert!(!p.key.is_empty(), "{p:?}");
                let _ = p.to_string();
            }
        }
        Ok(()) => valid(&config),
    }
}

/// What a configuration that validated must allow: `check-config`'s summary and the values
/// `mgmot run` derives from it at start-up.
fn valid(config: &Config) {
    let _ = summary(config);
    assert!(mgmot::mavlink::parse_connection(&config.mavlink.connection).is_ok());
    if let Some(s) = &config.mavlink.signing {
        assert!(s.key().is_some(), "validated signing key unusable: {s:?}");
    }
    if let DetectorConfig::Onnx(onnx) = &config.detector {
        let _ = onnx.settings();
    }
    if let Err(e) = mgmot::track::Tracker::new(config.tracker.clone()) {
        panic!("validated tracker parameters refused: {e}");
    }
    // src/pipeline/run.rs starts the heartbeat task with
    // `Duration::from_secs_f64(1.0 / config.outputs.heartbeat_hz)`, which panics when the
    // period is no Duration.
    let hz = config.outputs.heartbeat_hz;
    assert!(
        Duration::try_from_secs_f64(1.0 / hz).is_ok(),
        "outputs.heartbeat_hz = {hz:e} validates, but 1 / heartbeat_hz s is no Duration \
         (mgmot run panics)"
    );
}

/// The lines `mgmot check-config` prints for a valid configuration (src/cli/check_config.rs).
fn summary(config: &Config) -> String {
    let frames = match &config.frames {
        FramesConfig::V4l2 {
            device,
            pixel_format,
            width_px,
            height_px,
            fps,
            ..
        } => format!(
            "v4l2 {} {pixel_format} {width_px}x{height_px} @ {fps} fps",
            device.display()
        ),
        FramesConfig::Sim { socket, .. } => format!("simulator socket {}", socket.display()),
        FramesConfig::Images { directory, fps, .. } => {
            format!("images in {} @ {fps} fps", directory.display())
        }
    };
    format!(
        "  mavlink: {} as {}/{}\n  frames: {frames}\n  outputs: tracks at {} Hz, heartbeat at {} Hz",
        config.mavlink.connection,
        config.mavlink.system_id,
        config.mavlink.component_id,
        config.outputs.track_rate_hz,
        config.outputs.heartbeat_hz
    )
}
