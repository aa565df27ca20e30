//! Validation of a parsed scenario ([`Scenario::validate`]): ranges and cross-references,
//! every offending field named, in schema order.

use super::{
    Camera, Detector, Drone, EventKind, Faults, FieldProblem, Gimbal, GimbalMode, ObjectClass,
    Path2d, Render, Scenario, ScenarioError, Sea, Telemetry,
};

/// The problems found so far by [`Scenario::validate`].
#[derive(Debug, Default)]
struct Problems(Vec<FieldProblem>);

impl Problems {
    /// Records a problem with `field` unless `ok`.
    fn require(&mut self, ok: bool, field: &str, problem: &str) {
        if !ok {
            self.0.push(FieldProblem {
                field: field.to_string(),
                problem: problem.to_string(),
            });
        }
    }
}

impl Scenario {
    /// Checks ranges and cross-references; the error names every offending field.
    pub fn validate(&self, origin: &str) -> Result<(), ScenarioError> {
        let mut p = Problems::default();
        self.check_flight(&mut p);
        check_drone(&self.drone, &mut p);
        check_path(&self.drone.path, &mut p);
        check_gimbal(&self.gimbal, &mut p);
        check_camera(&self.camera, &mut p);
        check_sea(&self.sea, &mut p);
        self.check_objects(&mut p);
        self.check_events(&mut p);
        check_faults(&self.faults, &mut p);
        check_telemetry(&self.telemetry, &mut p);
        check_detector(&self.detector, &mut p);
        check_render(&self.render, &mut p);
        self.check_vehicles(&mut p);
        if p.0.is_empty() {
            Ok(())
        } else {
            Err(ScenarioError::Invalid {
                origin: origin.to_string(),
                problems: p.0,
            })
        }
    }

    /// `vehicles[i]`: each one's drone, path, gimbal and camera as the top level's, and a
    /// system id of its own.
    fn check_vehicles(&self, p: &mut Problems) {
        let mut ids = vec![self.telemetry.system_id];
        for (i, v) in self.vehicles.iter().enumerate() {
            let mut own = Problems::default();
            check_drone(&v.drone, &mut own);
            check_path(&v.drone.path, &mut own);
            if let Some(g) = &v.gimbal {
                check_gimbal(g, &mut own);
            }
            if let Some(c) = &v.camera {
                check_camera(c, &mut own);
            }
            own.require(
                v.system_id > 0 && !ids.contains(&v.system_id),
                "system_id",
                "must be 1..=255 and differ from telemetry.system_id and every other vehicle's",
            );
            ids.push(v.system_id);
            p.0.extend(own.0.into_iter().map(|f| FieldProblem {
                field: format!("vehicles[{i}].{}", f.field),
                problem: f.problem,
            }));
        }
    }

    /// `duration_s` and `origin`.
    fn check_flight(&self, p: &mut Problems) {
        let o = &self.origin;
        p.require(
            finite(self.duration_s) && self.duration_s > 0.0 && self.duration_s <= 86_400.0,
            "duration_s",
            "must be in (0, 86400]",
        );
        p.require(
            finite(o.lat_deg) && o.lat_deg.abs() <= 89.0,
            "origin.lat_deg",
            "must be within [-89, 89]",
        );
        p.require(
            finite(o.lon_deg) && o.lon_deg.abs() <= 180.0,
            "origin.lon_deg",
            "must be within [-180, 180]",
        );
        p.require(
            finite(o.alt_amsl_m) && finite(o.start_unix_s),
            "origin",
            "values must be finite",
        );
    }

    /// `objects[i]`, and their total count.
    fn check_objects(&self, p: &mut Problems) {
        let total: u64 = self.objects.iter().map(|o| u64::from(o.count)).sum();
        p.require(
            total <= 10_000,
            "objects",
            "more than 10000 objects in total",
        );
        for (i, o) in self.objects.iter().enumerate() {
            let field = |name: &str| format!("objects[{i}].{name}");
            if let Some([lo, hi]) = o.speed_mps {
                p.require(
                    finite(lo) && finite(hi) && 0.0 <= lo && lo <= hi && hi <= 40.0,
                    &field("speed_mps"),
                    "must be [min, max] with 0 <= min <= max <= 40",
                );
            }
            p.require(
                finite(o.spawn_radius_m) && o.spawn_radius_m >= 0.0,
                &field("spawn_radius_m"),
                "must be >= 0",
            );
            p.require(
                finite(o.random_walk) && (0.0..=5.0).contains(&o.random_walk),
                &field("random_walk"),
                "must be within [0, 5]",
            );
            if let Some([l, w]) = o.size_m {
                p.require(
                    finite(l) && finite(w) && l > 0.05 && w > 0.05 && l < 100.0 && w < 100.0,
                    &field("size_m"),
                    "must be within (0.05, 100)",
                );
            }
        }
    }

    /// `events[i]`: each names an existing group and member, and fits its group's class.
    fn check_events(&self, p: &mut Problems) {
        for (i, e) in self.events.iter().enumerate() {
            let field = |name: &str| format!("events[{i}].{name}");
            let group = self.objects.get(e.group);
            match group {
                None => p.require(
                    false,
                    &field("group"),
                    &format!(
                        "no object group {} (there are {})",
                        e.group,
                        self.objects.len()
                    ),
                ),
                Some(g) => p.require(
                    e.member < g.count,
                    &field("member"),
                    &format!("group {} has only {} objects", e.group, g.count),
                ),
            }
            p.require(
                finite(e.at_s) && e.at_s >= 0.0,
                &field("at_s"),
                "must be >= 0",
            );
            match (e.kind, group) {
                (EventKind::RemoveLifejacket, Some(g)) => p.require(
                    g.class == ObjectClass::Swimmer,
                    &field("kind"),
                    "remove_lifejacket needs a swimmer group",
                ),
                (EventKind::ChangeClass, _) => {
                    p.require(e.to.is_some(), &field("to"), "change_class needs `to`")
                }
                (EventKind::Stop | EventKind::Resume, Some(g)) => p.require(
                    g.class != ObjectClass::Buoy,
                    &field("kind"),
                    "buoys are moored: they cannot stop or resume",
                ),
                (EventKind::RemoveLifejacket | EventKind::Stop | EventKind::Resume, None) => {}
            }
            if e.kind == EventKind::Resume {
                let stopped_before = self.events.iter().any(|s| {
                    s.kind == EventKind::Stop
                        && s.group == e.group
                        && s.member == e.member
                        && s.at_s < e.at_s
                });
                p.require(
                    stopped_before,
                    &field("kind"),
                    "resume needs an earlier stop of the same object",
                );
            }
        }
    }
}

fn finite(v: f64) -> bool {
    v.is_finite()
}

/// `drone.*` but the path.
fn check_drone(d: &Drone, p: &mut Problems) {
    p.require(
        finite(d.speed_mps) && (0.0..=40.0).contains(&d.speed_mps),
        "drone.speed_mps",
        "must be within [0, 40]",
    );
    p.require(
        finite(d.altitude_m) && (1.0..=2000.0).contains(&d.altitude_m),
        "drone.altitude_m",
        "must be within [1, 2000]",
    );
    p.require(
        finite(d.max_yaw_rate_deg_s) && d.max_yaw_rate_deg_s > 0.0,
        "drone.max_yaw_rate_deg_s",
        "must be > 0",
    );
    for (field, profile, lo, hi) in [
        ("drone.speed_profile", &d.speed_profile, 0.0, 40.0),
        ("drone.altitude_profile", &d.altitude_profile, 1.0, 2000.0),
    ] {
        if let Err(problem) = check_profile(profile, lo, hi) {
            p.require(false, field, &problem);
        }
    }
}

/// `drone.path`, by kind.
fn check_path(path: &Path2d, p: &mut Problems) {
    let all_finite = |v: &[f64]| v.iter().all(|v| finite(*v));
    match path {
        Path2d::Hover {
            at_ne_m,
            heading_deg,
        } => p.require(
            all_finite(at_ne_m) && finite(*heading_deg),
            "drone.path",
            "values must be finite",
        ),
        Path2d::Waypoints { points_ne_m, .. } => {
            if points_ne_m.len() < 2 {
                p.require(false, "drone.path.points_ne_m", "needs at least two points");
            } else {
                p.require(
                    all_finite(points_ne_m.as_flattened()),
                    "drone.path.points_ne_m",
                    "values must be finite",
                );
            }
        }
        Path2d::Loiter {
            center_ne_m,
            radius_m,
            ..
        } => {
            p.require(
                finite(*radius_m) && *radius_m >= 1.0,
                "drone.path.radius_m",
                "must be >= 1",
            );
            p.require(
                all_finite(center_ne_m),
                "drone.path.center_ne_m",
                "values must be finite",
            );
        }
        Path2d::Lawnmower { .. } => check_lawnmower(path, p),
        Path2d::ExpandingSquare {
            datum_ne_m,
            first_heading_deg,
            spacing_m,
            legs,
            ..
        } => {
            p.require(
                finite(*spacing_m) && *spacing_m > 1.0,
                "drone.path.spacing_m",
                "must be > 1",
            );
            p.require(
                (1..=1000).contains(legs),
                "drone.path.legs",
                "must be within [1, 1000]",
            );
            p.require(
                all_finite(datum_ne_m) && finite(*first_heading_deg),
                "drone.path",
                "values must be finite",
            );
        }
        Path2d::Sector {
            datum_ne_m,
            radius_m,
            first_heading_deg,
            patterns,
            ..
        } => {
            p.require(
                finite(*radius_m) && *radius_m > 1.0,
                "drone.path.radius_m",
                "must be > 1",
            );
            p.require(
                (1..=6).contains(patterns),
                "drone.path.patterns",
                "must be within [1, 6]",
            );
            p.require(
                all_finite(datum_ne_m) && finite(*first_heading_deg),
                "drone.path",
                "values must be finite",
            );
        }
    }
}

/// `drone.path` of kind `lawnmower` (nothing for another kind).
fn check_lawnmower(path: &Path2d, p: &mut Problems) {
    let Path2d::Lawnmower {
        start_ne_m,
        heading_deg,
        leg_length_m,
        spacing_m,
        legs,
    } = path
    else {
        return;
    };
    p.require(
        finite(*leg_length_m) && *leg_length_m > 1.0,
        "drone.path.leg_length_m",
        "must be > 1",
    );
    p.require(
        finite(*spacing_m) && *spacing_m > 0.0,
        "drone.path.spacing_m",
        "must be > 0",
    );
    p.require(
        (1..=1000).contains(legs),
        "drone.path.legs",
        "must be within [1, 1000]",
    );
    p.require(
        start_ne_m.iter().all(|v| finite(*v)) && finite(*heading_deg),
        "drone.path",
        "values must be finite",
    );
}

/// `gimbal.*`; the sweep and swing fields only in their modes.
fn check_gimbal(g: &Gimbal, p: &mut Problems) {
    p.require(
        finite(g.pitch_deg) && (0.0..=90.0).contains(&g.pitch_deg),
        "gimbal.pitch_deg",
        "must be within [0, 90] (below the horizon)",
    );
    if g.mode == GimbalMode::Sweep {
        p.require(
            finite(g.sweep_period_s) && g.sweep_period_s > 0.1,
            "gimbal.sweep_period_s",
            "must be > 0.1",
        );
    }
    if g.mode == GimbalMode::Swings {
        p.require(
            finite(g.swing_interval_s) && g.swing_interval_s > 0.1,
            "gimbal.swing_interval_s",
            "must be > 0.1",
        );
        p.require(
            finite(g.swing_rate_deg_s) && g.swing_rate_deg_s > 0.0,
            "gimbal.swing_rate_deg_s",
            "must be > 0",
        );
    }
}

/// `camera.*`.
fn check_camera(c: &Camera, p: &mut Problems) {
    p.require(
        (16..=7680).contains(&c.width_px),
        "camera.width_px",
        "must be within [16, 7680]",
    );
    p.require(
        (16..=4320).contains(&c.height_px),
        "camera.height_px",
        "must be within [16, 4320]",
    );
    p.require(
        finite(c.hfov_deg) && c.hfov_deg > 1.0 && c.hfov_deg < 170.0,
        "camera.hfov_deg",
        "must be within (1, 170)",
    );
    p.require(
        finite(c.fps) && c.fps > 0.0 && c.fps <= 240.0,
        "camera.fps",
        "must be within (0, 240]",
    );
    p.require(
        finite(c.capture_latency_ms) && c.capture_latency_ms >= 0.0,
        "camera.capture_latency_ms",
        "must be >= 0",
    );
}

/// `sea.*`.
fn check_sea(s: &Sea, p: &mut Problems) {
    p.require(
        s.current_ne_mps.iter().all(|v| finite(*v))
            && s.current_ne_mps[0].hypot(s.current_ne_mps[1]) <= 5.0,
        "sea.current_ne_mps",
        "must be finite, at most 5 m/s",
    );
    p.require(
        s.wind_ne_mps.iter().all(|v| finite(*v))
            && s.wind_ne_mps[0].hypot(s.wind_ne_mps[1]) <= 40.0,
        "sea.wind_ne_mps",
        "must be finite, at most 40 m/s",
    );
    p.require(
        finite(s.wave_length_m) && s.wave_length_m > 0.1,
        "sea.wave_length_m",
        "must be > 0.1",
    );
    p.require(
        finite(s.wave_height_m) && s.wave_height_m >= 0.0,
        "sea.wave_height_m",
        "must be >= 0",
    );
    p.require(
        finite(s.sun_elevation_deg) && (0.0..=90.0).contains(&s.sun_elevation_deg),
        "sea.sun_elevation_deg",
        "must be within [0, 90]",
    );
    p.require(
        finite(s.glint) && (0.0..=1.0).contains(&s.glint),
        "sea.glint",
        "must be within [0, 1]",
    );
}

/// `render.*`.
fn check_render(r: &Render, p: &mut Problems) {
    p.require(
        finite(r.camera_noise) && (0.0..=2.5).contains(&r.camera_noise),
        "render.camera_noise",
        "must be within [0, 2.5]",
    );
    p.require(
        finite(r.vignetting) && (0.0..=1.0).contains(&r.vignetting),
        "render.vignetting",
        "must be within [0, 1]",
    );
    p.require(
        finite(r.exposure_s) && (0.0..=0.1).contains(&r.exposure_s),
        "render.exposure_s",
        "must be within [0, 0.1]",
    );
    p.require(
        (1..=100).contains(&r.jpeg_quality),
        "render.jpeg_quality",
        "must be within [1, 100]",
    );
}

/// `faults.*`.
fn check_faults(f: &Faults, p: &mut Problems) {
    for (j, w) in f.dropouts.iter().enumerate() {
        p.require(
            finite(w[0]) && finite(w[1]) && w[0] >= 0.0 && w[1] > 0.0,
            &format!("faults.dropouts[{j}]"),
            "must be [start_s >= 0, duration_s > 0]",
        );
    }
    for (field, v) in [
        ("faults.telemetry_latency_ms", f.telemetry_latency_ms),
        ("faults.attitude_noise_deg", f.attitude_noise_deg),
        ("faults.gimbal_noise_deg", f.gimbal_noise_deg),
        ("faults.gps_noise_m", f.gps_noise_m),
    ] {
        p.require(finite(v) && v >= 0.0, field, "must be >= 0");
    }
    for (j, r) in f.reboots_s.iter().enumerate() {
        p.require(
            finite(*r) && *r >= 0.0,
            &format!("faults.reboots_s[{j}]"),
            "must be a time >= 0",
        );
    }
}

/// `telemetry.*`.
fn check_telemetry(t: &Telemetry, p: &mut Problems) {
    p.require(
        finite(t.rate_jitter) && (0.0..0.5).contains(&t.rate_jitter),
        "telemetry.rate_jitter",
        "must be within [0, 0.5)",
    );
    p.require(
        finite(t.boot_time_s) && t.boot_time_s >= 0.0,
        "telemetry.boot_time_s",
        "must be >= 0",
    );
}

/// `detector.*`.
fn check_detector(det: &Detector, p: &mut Problems) {
    p.require(
        finite(det.miss_floor) && (0.0..=1.0).contains(&det.miss_floor),
        "detector.miss_floor",
        "must be within [0, 1]",
    );
    p.require(
        finite(det.false_positives_per_frame) && det.false_positives_per_frame >= 0.0,
        "detector.false_positives_per_frame",
        "must be >= 0",
    );
}

fn check_profile(profile: &[[f64; 2]], lo: f64, hi: f64) -> Result<(), String> {
    let mut last_t = f64::NEG_INFINITY;
    for (i, [t, v]) in profile.iter().enumerate() {
        if !t.is_finite() || !v.is_finite() {
            return Err(format!("entry {i}: values must be finite"));
        }
        if *t <= last_t {
            return Err(format!("entry {i}: times must increase"));
        }
        if *v < lo || *v > hi {
            return Err(format!("entry {i}: value {v} outside [{lo}, {hi}]"));
        }
        last_t = *t;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::scenario::*;

    #[test]
    fn out_of_range_field_is_named() {
        let text = SHIPPED[0].1.replace("fps = 30", "fps = -2");
        let err = Scenario::from_toml(&text, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("camera.fps"), "{err}");
    }

    /// Three mistakes in three parts of the file: all three are reported, each with its field
    /// and its own message, in schema order.
    #[test]
    fn every_invalid_field_is_reported() {
        let text = SHIPPED[0]
            .1
            .replace("fps = 30", "fps = -2")
            .replace("glint = 0.4", "glint = 2")
            + "\n[telemetry]\nboot_time_s = -1\n";
        let err = Scenario::from_toml(&text, "x.toml").unwrap_err();
        let ScenarioError::Invalid { origin, problems } = &err else {
            panic!("{err}")
        };
        assert_eq!(origin, "x.toml");
        let fields: Vec<&str> = problems.iter().map(|p| p.field.as_str()).collect();
        assert_eq!(fields, ["camera.fps", "sea.glint", "telemetry.boot_time_s"]);
        assert_eq!(
            err.to_string(),
            "invalid scenario x.toml: field `camera.fps`: must be within (0, 240]; \
             field `sea.glint`: must be within [0, 1]; \
             field `telemetry.boot_time_s`: must be >= 0"
        );
    }

    #[test]
    fn an_event_of_a_missing_group_is_reported_with_the_rest() {
        let mut s = Scenario::load("calm_baseline").unwrap();
        s.duration_s = 0.0;
        s.events.push(Event {
            at_s: -1.0,
            group: 99,
            member: 0,
            kind: EventKind::ChangeClass,
            to: None,
        });
        let Err(ScenarioError::Invalid { problems, .. }) = s.validate("t") else {
            panic!("validated")
        };
        let n = s.events.len() - 1;
        let fields: Vec<String> = problems.into_iter().map(|p| p.field).collect();
        assert_eq!(
            fields,
            [
                "duration_s".to_string(),
                format!("events[{n}].group"),
                format!("events[{n}].at_s"),
                format!("events[{n}].to")
            ]
        );
    }

    fn event(kind: EventKind, group: usize, member: u32, at_s: f64) -> Event {
        Event {
            kind,
            group,
            member,
            at_s,
            to: None,
        }
    }

    /// `stop` and `resume` are checked like the other events (group, member), plus their own
    /// rules: not on a buoy, and a resume only after a stop of the same object.
    #[test]
    fn stop_and_resume_are_validated() {
        let mut s = Scenario::load("lawnmower_search").unwrap();
        let buoy = s
            .objects
            .iter()
            .position(|g| g.class == ObjectClass::Buoy)
            .unwrap();
        let swimmers = s
            .objects
            .iter()
            .position(|g| g.class == ObjectClass::Swimmer)
            .unwrap();
        let n = s.events.len();
        s.events.extend([
            event(EventKind::Stop, buoy, 0, 10.0),
            event(EventKind::Stop, swimmers, 9999, 10.0),
            event(EventKind::Resume, swimmers, 1, 10.0),
            event(EventKind::Stop, swimmers, 2, 20.0),
            event(EventKind::Resume, swimmers, 2, 19.0),
            event(EventKind::Stop, 99, 0, 10.0),
        ]);
        let Err(ScenarioError::Invalid { problems, .. }) = s.validate("t") else {
            panic!("validated")
        };
        let fields: Vec<String> = problems.into_iter().map(|p| p.field).collect();
        assert_eq!(
            fields,
            [
                format!("events[{n}].kind"),
                format!("events[{}].member", n + 1),
                format!("events[{}].kind", n + 2),
                format!("events[{}].kind", n + 4),
                format!("events[{}].group", n + 5),
            ]
        );
        // A stop and a later resume of a swimmer are fine.
        s.events.truncate(n);
        s.events.push(event(EventKind::Stop, swimmers, 2, 20.0));
        s.events.push(event(EventKind::Resume, swimmers, 2, 40.0));
        s.validate("t").unwrap();
    }

    #[test]
    fn wind_defaults_to_calm_and_is_range_checked() {
        let s = Scenario::load("mixed_mission_soak").unwrap();
        assert_eq!(s.sea.wind_ne_mps, [0.0, 0.0]);
        let text = SHIPPED[0]
            .1
            .replace("[sea]", "[sea]\nwind_ne_mps = [50.0, 0.0]");
        let err = Scenario::from_toml(&text, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("sea.wind_ne_mps"), "{err}");
    }

    #[test]
    fn new_path_kinds_are_range_checked() {
        let base = SHIPPED[0].1;
        let start = base.find("[drone.path]").unwrap();
        let end = start + base[start..].find("\n\n").unwrap();
        for (path, field) in [
            (
                "kind = \"expanding_square\"\ndatum_ne_m = [0.0, 0.0]\nfirst_heading_deg = 0.0\nspacing_m = 0.5\nlegs = 4",
                "drone.path.spacing_m",
            ),
            (
                "kind = \"sector\"\ndatum_ne_m = [0.0, 0.0]\nfirst_heading_deg = 0.0\nradius_m = 100.0\npatterns = 0",
                "drone.path.patterns",
            ),
        ] {
            let text = format!("{}[drone.path]\n{path}{}", &base[..start], &base[end..]);
            let err = Scenario::from_toml(&text, "x.toml")
                .unwrap_err()
                .to_string();
            assert!(err.contains(field), "{err}");
        }
    }
}
