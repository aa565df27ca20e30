//! The scenarios shipped with the simulator (`sim/scenarios/*.toml`), embedded in the binary:
//! `mgmot-sim list` lists them and [`Scenario::load`](super::Scenario::load) resolves their
//! names before file paths.

/// The scenarios shipped with the simulator: (name, TOML text).
pub const SHIPPED: &[(&str, &str)] = &[
    (
        "calm_baseline",
        include_str!("../../scenarios/calm_baseline.toml"),
    ),
    (
        "fast_drone",
        include_str!("../../scenarios/fast_drone.toml"),
    ),
    (
        "gimbal_swings",
        include_str!("../../scenarios/gimbal_swings.toml"),
    ),
    (
        "leave_and_return",
        include_str!("../../scenarios/leave_and_return.toml"),
    ),
    (
        "high_altitude_tiny",
        include_str!("../../scenarios/high_altitude_tiny.toml"),
    ),
    (
        "swimmer_group",
        include_str!("../../scenarios/swimmer_group.toml"),
    ),
    (
        "boats_crossing",
        include_str!("../../scenarios/boats_crossing.toml"),
    ),
    (
        "camera_desync",
        include_str!("../../scenarios/camera_desync.toml"),
    ),
    (
        "gimbal_pitch_bias",
        include_str!("../../scenarios/gimbal_pitch_bias.toml"),
    ),
    (
        "telemetry_dropout",
        include_str!("../../scenarios/telemetry_dropout.toml"),
    ),
    (
        "mixed_mission_soak",
        include_str!("../../scenarios/mixed_mission_soak.toml"),
    ),
    (
        "ardupilot_servo",
        include_str!("../../scenarios/ardupilot_servo.toml"),
    ),
    (
        "lawnmower_search",
        include_str!("../../scenarios/lawnmower_search.toml"),
    ),
    (
        "expanding_square",
        include_str!("../../scenarios/expanding_square.toml"),
    ),
    (
        "sector_search",
        include_str!("../../scenarios/sector_search.toml"),
    ),
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    #[test]
    fn every_shipped_scenario_loads() {
        for (name, _) in SHIPPED {
            let s = Scenario::load(name).unwrap();
            assert_eq!(&s.name, name);
        }
    }
}
