//! The runtime configuration: `Config::parse` then `validate`, and what `mgmot check-config`
//! and `mgmot run` do with the settings of a configuration that validated.

use mgmot::config::{Config, DetectorSettings, FrameSettings, Settings};
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
            // The frames section alone finds its own problems, and only those.
            if let Err(frames) = config.frames.settings() {
                assert!(frames.iter().all(|p| problems.contains(p)), "{frames:?}");
            }
        }
        Ok(settings) => valid(&config, &settings),
    }
}

/// What the settings of a configuration that validated must allow: `check-config`'s summary
/// and the values `mgmot run` derives from them at start-up.
fn valid(config: &Config, settings: &Settings) {
    // `mgmot check-config`'s frames line, and the capture start's settings (the same).
    let _ = settings.frames.to_string();
    assert_eq!(config.frames.settings().as_ref(), Ok(&settings.frames));
    if let FrameSettings::V4l2 { camera, reconnect } = &settings.frames {
        assert!(camera.frame_timeout > Duration::ZERO && reconnect.max >= reconnect.initial);
    }
    assert!(mgmot::mavlink::parse_connection(&settings.mavlink.connection).is_ok());
    if let Some(s) = &config.mavlink.signing {
        assert_eq!(
            s.key(),
            settings.mavlink.signing.as_ref().map(|s| s.key),
            "validated signing key unusable: {s:?}"
        );
    }
    if let DetectorSettings::Onnx(onnx) = &settings.detector {
        assert!(
            onnx.detector.threads >= 1 && onnx.detector.max_detections >= 1,
            "{onnx:?}"
        );
    }
    if let Err(e) = mgmot::track::Tracker::new(settings.tracker.clone()) {
        panic!("validated tracker parameters refused: {e}");
    }
    // src/pipeline/run.rs starts the heartbeat task with
    // `Duration::from_secs_f64(1.0 / config.outputs.heartbeat_hz)`, which panics when the
    // period is no Duration; the settings hold that period.
    let hz = config.outputs.heartbeat_hz;
    assert_eq!(
        Duration::try_from_secs_f64(1.0 / hz).ok(),
        Some(settings.outputs.heartbeat_every),
        "outputs.heartbeat_hz = {hz:e} validates, but 1 / heartbeat_hz s is no Duration \
         (mgmot run panics)"
    );
}
