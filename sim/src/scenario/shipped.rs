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
    (
        "two_drones",
        include_str!("../../scenarios/two_drones.toml"),
    ),
    (
        "two_drones_abreast",
        include_str!("../../scenarios/two_drones_abreast.toml"),
    ),
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    /// The two drones of `two_drones` fly different patterns with their own system ids over
    /// the same objects, and both see most of them.
    #[test]
    fn two_drones_share_one_world_and_see_the_same_objects() {
        use crate::truth::{frame_truth, Optics};
        use crate::world::World;
        use std::collections::BTreeSet;
        let s = Scenario::load("two_drones").unwrap();
        let worlds: Vec<World> = (0..2)
            .map(|k| World::new(s.for_vehicle(k).unwrap(), s.seed))
            .collect();
        assert_eq!(worlds[0].scenario.telemetry.system_id, 1);
        assert_eq!(worlds[1].scenario.telemetry.system_id, 2);
        for t in [0.0, 60.0, 179.0] {
            let (a, b) = (worlds[0].objects_at(t), worlds[1].objects_at(t));
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(&b) {
                assert_eq!(
                    (x.id, x.pos_ned_m),
                    (y.id, y.pos_ned_m),
                    "same objects at {t} s"
                );
            }
            let (da, db) = (worlds[0].truth(t), worlds[1].truth(t));
            assert_ne!(da.pos_ned_m, db.pos_ned_m, "different drones at {t} s");
            // Each drone's GNSS errs on its own: the reported-minus-true offsets differ.
            let (ra, rb) = (worlds[0].reported(t), worlds[1].reported(t));
            let err = |r: [f64; 3], d: [f64; 3]| [r[0] - d[0], r[1] - d[1]];
            let (ea, eb) = (
                err(ra.pos_ned_m, da.pos_ned_m),
                err(rb.pos_ned_m, db.pos_ned_m),
            );
            assert!(
                (ea[0] - eb[0]).hypot(ea[1] - eb[1]) > 1e-3,
                "same GPS error at {t} s: {ea:?} {eb:?}"
            );
        }
        // Vehicle 0 draws as the scenario alone does (a one-drone flight is unchanged).
        let alone = World::new(s.clone(), s.seed);
        for t in [0.0, 60.0] {
            assert_eq!(alone.reported(t).pos_ned_m, worlds[0].reported(t).pos_ned_m);
        }
        let seen: Vec<BTreeSet<u32>> = worlds
            .iter()
            .map(|w| {
                let optics = Optics::new(&w.scenario).unwrap();
                (0..w.scenario.frame_count())
                    .step_by(15)
                    .flat_map(|i| frame_truth(w, &optics, i).boxes)
                    .map(|b| b.object.id)
                    .collect()
            })
            .collect();
        let both = seen[0].intersection(&seen[1]).count();
        let total = worlds[0].objects_at(0.0).len();
        assert!(
            both * 2 >= total,
            "only {both} of {total} objects seen by both: {seen:?}"
        );
        let err = s.for_vehicle(2).unwrap_err().to_string();
        assert!(err.contains("0 to 1") && err.contains("vehicle 2"), "{err}");
    }

    #[test]
    fn a_vehicle_needs_a_system_id_of_its_own() {
        let text = include_str!("../../scenarios/two_drones.toml")
            .replace("system_id = 2", "system_id = 1")
            .replace("legs = 4\n[vehicles.gimbal]", "legs = 0\n[vehicles.gimbal]");
        let err = Scenario::from_toml(&text, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("vehicles[0].system_id"), "{err}");
        assert!(err.contains("vehicles[0].drone.path"), "{err}");
    }

    #[test]
    fn every_shipped_scenario_loads() {
        for (name, _) in SHIPPED {
            let s = Scenario::load(name).unwrap();
            assert_eq!(&s.name, name);
        }
    }
}
