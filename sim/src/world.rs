//! The simulated world of one scenario run: the true drone/camera trajectory, the objects,
//! and the metadata the autopilot *reports* (truth plus the scenario's faults).
//!
//! Everything is precomputed from the scenario and the seed, so the world is immutable
//! and any instant can be queried from any thread in any order.

use crate::motion::{wrap_360, DroneState, DroneTrack, DRONE_DT_S};
use crate::objects::{ObjectState, SimObject};
use crate::scenario::Scenario;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// RNG stream of the metadata faults.
const STREAM_FAULTS: u64 = 2;

/// Correlation time of the GPS error (first-order Gauss-Markov), typical of a
/// consumer GNSS receiver.
const GPS_CORRELATION_S: f64 = 5.0;

/// How long a rebooting autopilot is silent; its `time_boot_ms` is this at its first message.
pub const REBOOT_SILENCE_S: f64 = 3.0;

/// Everything about one run.
#[derive(Debug, Clone)]
pub struct World {
    /// The scenario (validated).
    pub scenario: Scenario,
    /// The seed in use (scenario seed or the `--seed` override).
    pub seed: u64,
    /// True drone and camera trajectory.
    pub drone: DroneTrack,
    /// Every object, ids 1..=len in order.
    pub objects: Vec<SimObject>,
    /// Per-sample fault noise, aligned with the drone table.
    noise: Vec<FaultNoise>,
}

/// Noise values of one drone-table sample.
#[derive(Debug, Clone, Copy, Default)]
struct FaultNoise {
    attitude_deg: [f64; 3],
    gimbal_deg: [f64; 2],
    gps_ne_m: [f64; 2],
}

/// What the autopilot reports at one instant: the same quantities as the truth
/// ([`DroneState`]), with the scenario's faults applied (GPS noise, altitude bias, attitude
/// bias and noise).
pub type Reported = DroneState;

impl World {
    /// Builds the world of `scenario` with `seed`.
    pub fn new(scenario: Scenario, seed: u64) -> World {
        let drone = DroneTrack::generate(&scenario, seed);
        let objects = crate::objects::generate(&scenario, seed);
        let n = ((scenario.duration_s + 2.0) / DRONE_DT_S).ceil() as usize + 1;
        let f = &scenario.faults;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(scenario.vehicle_stream(STREAM_FAULTS));
        let mut gauss = || -> f64 { StandardNormal.sample(&mut rng) };
        let phi = (-DRONE_DT_S / GPS_CORRELATION_S).exp();
        let drive = (1.0 - phi * phi).sqrt();
        let mut gps = [f.gps_noise_m * gauss(), f.gps_noise_m * gauss()];
        let mut noise = Vec::with_capacity(n);
        for _ in 0..n {
            let attitude_deg = [
                f.attitude_noise_deg * gauss(),
                f.attitude_noise_deg * gauss(),
                f.attitude_noise_deg * gauss(),
            ];
            let gimbal_deg = [f.gimbal_noise_deg * gauss(), f.gimbal_noise_deg * gauss()];
            for g in &mut gps {
                *g = phi * *g + drive * f.gps_noise_m * gauss();
            }
            noise.push(FaultNoise {
                attitude_deg,
                gimbal_deg,
                gps_ne_m: gps,
            });
        }
        World {
            scenario,
            seed,
            drone,
            objects,
            noise,
        }
    }

    /// True drone/camera state at `t_s`.
    pub fn truth(&self, t_s: f64) -> DroneState {
        self.drone.at(t_s)
    }

    /// Every object that exists at `t_s`, in id order.
    pub fn objects_at(&self, t_s: f64) -> Vec<ObjectState> {
        self.objects.iter().filter_map(|o| o.at(t_s)).collect()
    }

    /// What the autopilot reports about instant `t_s` (without latency or dropouts: those
    /// are about *when* it is sent, see [`World::in_dropout`]).
    pub fn reported(&self, t_s: f64) -> Reported {
        let truth = self.drone.at(t_s);
        let f = &self.scenario.faults;
        let k =
            ((t_s.max(0.0) / DRONE_DT_S).round() as usize).min(self.noise.len().saturating_sub(1));
        let nz = self.noise.get(k).copied().unwrap_or_default();
        Reported {
            pos_ned_m: [
                truth.pos_ned_m[0] + nz.gps_ne_m[0],
                truth.pos_ned_m[1] + nz.gps_ne_m[1],
                truth.pos_ned_m[2] - f.altitude_bias_m,
            ],
            vel_ned_mps: truth.vel_ned_mps,
            roll_deg: truth.roll_deg + f.attitude_bias_deg[0] + nz.attitude_deg[0],
            pitch_deg: truth.pitch_deg + f.attitude_bias_deg[1] + nz.attitude_deg[1],
            yaw_deg: wrap_360(truth.yaw_deg + f.attitude_bias_deg[2] + nz.attitude_deg[2]),
            cam_heading_deg: wrap_360(
                truth.cam_heading_deg + f.gimbal_yaw_bias_deg + nz.gimbal_deg[0],
            ),
            cam_pitch_deg: (truth.cam_pitch_deg + f.gimbal_pitch_bias_deg + nz.gimbal_deg[1])
                .clamp(-90.0, 90.0),
        }
    }

    /// True when the telemetry link is down at `t_s` (a `faults.dropouts` window).
    pub fn in_dropout(&self, t_s: f64) -> bool {
        let f = &self.scenario.faults;
        f.dropouts
            .iter()
            .any(|[start, dur]| t_s >= *start && t_s < start + dur)
            || f.reboots_s
                .iter()
                .any(|r| t_s >= *r && t_s < r + REBOOT_SILENCE_S)
    }

    /// The latest reboot at or before `t_s` (`faults.reboots_s`).
    pub fn last_reboot_s(&self, t_s: f64) -> Option<f64> {
        self.scenario
            .faults
            .reboots_s
            .iter()
            .copied()
            .filter(|r| *r <= t_s)
            .max_by(f64::total_cmp)
    }

    /// The metadata a drone log would attach to the frame captured at true time `t_s`: the
    /// reported state at the frame's (offset) timestamp, or the last state received before
    /// a dropout while the link is down.
    pub fn frame_metadata(&self, t_s: f64) -> Reported {
        let stamped = t_s + self.scenario.faults.camera_time_offset_ms / 1000.0;
        let mut t = stamped;
        for [start, dur] in &self.scenario.faults.dropouts {
            if stamped >= *start && stamped < start + dur {
                t = *start;
            }
        }
        self.reported(t)
    }

    /// True capture time of frame `index`.
    pub fn frame_time_s(&self, index: u64) -> f64 {
        index as f64 / self.scenario.camera.fps
    }

    /// The autopilot clock (`time_boot_ms` in microseconds) at sim time `t_s`.
    /// After a reboot the clock starts again from 0 at the reboot.
    pub fn autopilot_time_us(&self, t_s: f64) -> u64 {
        let since_boot = match self.last_reboot_s(t_s) {
            Some(r) => t_s - r,
            None => self.scenario.telemetry.boot_time_s + t_s,
        };
        (since_boot.max(0.0) * 1e6).round() as u64
    }

    /// The timestamp a frame captured at true time `t_s` carries, on the autopilot's clock
    /// (includes the camera-vs-telemetry offset fault).
    pub fn frame_stamp_us(&self, t_s: f64) -> u64 {
        self.autopilot_time_us(t_s + self.scenario.faults.camera_time_offset_ms / 1000.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn biases_show_in_reports_not_truth() {
        let s = Scenario::load("gimbal_pitch_bias").unwrap();
        let w = World::new(s, 9);
        let mut sum = 0.0;
        for k in 0..200 {
            let t = k as f64 * 0.1;
            sum += w.reported(t).cam_pitch_deg - w.truth(t).cam_pitch_deg;
        }
        let mean = sum / 200.0;
        assert!((mean - 3.0).abs() < 0.05, "{mean}");
    }

    #[test]
    fn dropout_freezes_frame_metadata() {
        let s = Scenario::load("telemetry_dropout").unwrap();
        let w = World::new(s, 10);
        assert!(w.in_dropout(22.0));
        assert!(!w.in_dropout(25.5));
        assert_eq!(w.frame_metadata(21.0), w.frame_metadata(24.0));
        assert_ne!(w.frame_metadata(19.0), w.frame_metadata(21.0));
    }
}
