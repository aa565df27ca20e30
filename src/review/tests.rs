use super::build::{footprint, segments_of, thin, EDGE_SAMPLES};
use super::health::Health;
use super::truth::ErrorStats;
use super::*;
use crate::geo::attitude::camera_from_heading_pitch_deg;
use crate::geo::{Geodetic, LocalTangentFrame};
use crate::mavlink::dialect::{MavMessage, TIMESYNC_DATA};
use crate::record::format::FrameRecord;
use crate::record::format::PoseRecord;
use crate::record::tlog::TlogEntry;
use crate::track::MergeEvent;
use mavlink_core::{MavHeader, MavlinkVersion};

fn frame(n: u64) -> FrameRecord {
    FrameRecord {
        time_s: n as f64 * 0.1,
        autopilot_time_us: Some(n * 100_000),
        captured_unix_us: Some(1_000_000_000_000_000 + n * 100_000),
        processed_unix_us: 1_000_000_000_000_000 + n * 100_000 + 50_000,
        ..FrameRecord::empty(n, 1280, 720)
    }
}

#[test]
fn degrees_minutes_carry_and_hemispheres() {
    assert_eq!(dm(47.6721, 'N', 'S'), "47°40.326'N");
    assert_eq!(dm(-9.5, 'E', 'W'), "9°30.000'W");
    assert_eq!(dm(10.999_999_9, 'N', 'S'), "11°00.000'N");
    assert_eq!(dm(0.0, 'E', 'W'), "0°00.000'E");
}

#[test]
fn base64_matches_rfc_4648() {
    for (raw, enc) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(html::base64(raw.as_bytes()), enc);
    }
    assert_eq!(html::base64(&[0xff, 0xfe, 0x00]), "//4A");
}

#[test]
fn merges_are_followed_to_the_final_id_and_cycles_stop() {
    let mut frames = vec![frame(0), frame(1)];
    frames[0].merges.push(MergeEvent {
        new_id: 7,
        merged_into_id: 3,
        frame_index: 0,
    });
    frames[1].merges.push(MergeEvent {
        new_id: 3,
        merged_into_id: 1,
        frame_index: 1,
    });
    let m = Merges::of(&frames);
    assert_eq!(
        (m.final_id(7), m.final_id(3), m.final_id(1), m.final_id(9)),
        (1, 1, 1, 9)
    );
    frames[1].merges.push(MergeEvent {
        new_id: 1,
        merged_into_id: 7,
        frame_index: 1,
    });
    // A cycle (never sent) ends somewhere instead of looping.
    let m = Merges::of(&frames);
    let _ = m.final_id(7);
}

#[test]
fn segments_are_detected_coasting_or_lost_by_the_length_of_the_absence() {
    let times = [0.0, 0.1, 0.2, 0.3, 1.3, 1.4, 4.0];
    let s = segments_of(5, times.into_iter(), 0.1);
    let states: Vec<(&str, f64, f64)> = s.iter().map(|s| (s.state, s.t0, s.t1)).collect();
    assert_eq!(
        states,
        [
            ("detected", 0.0, 0.3),
            ("coasting", 0.3, 1.3),
            ("detected", 1.3, 1.4),
            ("lost", 1.4, 4.0),
            ("detected", 4.0, 4.0),
        ]
    );
    assert!(s.iter().all(|s| s.id == 5));
}

#[test]
fn thinning_keeps_the_ends_and_at_most_max() {
    assert_eq!(thin(3, 10), [0, 1, 2]);
    let v = thin(1000, 7);
    assert_eq!(v.len(), 7);
    assert_eq!((v[0], v[6]), (0, 999));
    assert!(thin(5, 0).is_empty());
}

#[test]
fn a_nadir_footprint_is_the_field_of_view_on_the_water() {
    let mut f = frame(0);
    let q = camera_from_heading_pitch_deg(0.0, 90.0, 0.0);
    f.pose = Some(PoseRecord {
        lat_deg: 47.0,
        lon_deg: 9.0,
        alt_m: 130.0,
        height_above_sea_m: 30.0,
        attitude_wxyz: [q.w, q.i, q.j, q.k],
        horizontal_accuracy_m: None,
    });
    let origin = Geodetic::new(47.0, 9.0, 100.0).unwrap();
    let fp = footprint(&f, origin, 70.0);
    assert_eq!(fp.len(), 4 * EDGE_SAMPLES);
    let width = 2.0 * 30.0 * 35f64.to_radians().tan();
    let height = width * 720.0 / 1280.0;
    let (mut min_e, mut max_e, mut min_n, mut max_n) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for [n, e] in &fp {
        min_n = min_n.min(*n);
        max_n = max_n.max(*n);
        min_e = min_e.min(*e);
        max_e = max_e.max(*e);
    }
    assert!(((max_e - min_e) - width).abs() < 0.05, "{}", max_e - min_e);
    assert!(((max_n - min_n) - height).abs() < 0.05, "{}", max_n - min_n);

    // Looking at the horizon: the upper part of the image is left out, not drawn to infinity.
    let q = camera_from_heading_pitch_deg(0.0, 5.0, 0.0);
    f.pose = Some(PoseRecord {
        attitude_wxyz: [q.w, q.i, q.j, q.k],
        ..f.pose.unwrap_or_else(|| unreachable!())
    });
    let fp = footprint(&f, origin, 70.0);
    assert!(!fp.is_empty() && fp.len() < 4 * EDGE_SAMPLES);
    assert!(fp
        .iter()
        .all(|[n, e]| n.hypot(*e) <= FOOTPRINT_MAX_RANGE_M + 1.0));
}

fn timesync(component_id: u8, tc1: i64, ts1: i64, unix_us: u64) -> TlogEntry {
    let mut packet = Vec::new();
    let header = MavHeader {
        system_id: 1,
        component_id,
        sequence: 0,
    };
    let m = MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1,
        ts1,
        ..Default::default()
    });
    mavlink_core::write_versioned_msg(&mut packet, MavlinkVersion::V2, header, &m)
        .unwrap_or_else(|e| panic!("{e}"));
    TlogEntry { unix_us, packet }
}

#[test]
fn timesync_pairs_mgmots_requests_with_the_autopilots_answers() {
    let t0 = 1_000_000_000_000_000;
    let tlog = [
        timesync(191, 0, 7_000_000_000, t0),
        // Someone else's answer (another ts1): not paired.
        timesync(1, 99, 5, t0 + 1_000),
        // The autopilot's clock is 250 ms ahead; the round trip takes 6 ms.
        timesync(
            1,
            7_000_000_000 + 250_000_000 + 3_000_000,
            7_000_000_000,
            t0 + 6_000,
        ),
        timesync(191, 0, 8_000_000_000, t0 + 1_000_000),
        timesync(
            1,
            8_000_000_000 + 252_000_000 + 1_000_000,
            8_000_000_000,
            t0 + 1_002_000,
        ),
    ];
    let h = Health::of(&[], &tlog, true, 1, 1, 191, t0);
    assert_eq!(h.timesync.len(), 2);
    assert!((h.timesync[0].offset_ms - 250.0).abs() < 1e-9);
    assert!((h.timesync[0].rtt_ms - 6.0).abs() < 1e-9);
    assert!((h.timesync[1].offset_ms - 252.0).abs() < 1e-9);
    assert!((h.timesync[1].t - 1.002).abs() < 1e-9);
    let from: Vec<(&str, &str, u64)> = h
        .rates
        .iter()
        .map(|r| (r.from.as_str(), r.name.as_str(), r.count))
        .collect();
    assert_eq!(
        from,
        [("autopilot", "TIMESYNC", 3), ("mgmot", "TIMESYNC", 2)]
    );
    assert!(h.gaps.is_empty(), "1.0 s is not a gap");
}

#[test]
fn error_statistics() {
    let s = ErrorStats::of(&[3.0, 1.0, 2.0, f64::NAN]);
    assert_eq!((s.n, s.median_m, s.p95_m, s.max_m), (3, 2.0, 3.0, 3.0));
    let s = ErrorStats::of(&[]);
    assert_eq!((s.n, s.max_m), (0, 0.0));
}

#[test]
fn the_embedded_data_cannot_close_its_script_element() {
    let flight = crate::record::Flight {
        dir: "x</script><script>alert(1)</script>".into(),
        info: crate::record::format::FlightInfo {
            format: crate::record::format::FORMAT.into(),
            version: 1,
            mgmot_version: "t".into(),
            started_utc: "2026-01-01T00:00:00Z".into(),
            started_unix_us: 0,
            system_id: 1,
            component_id: 191,
            detector: crate::record::format::DetectorIdentity {
                kind: "onnx".into(),
                file: "m&<>.onnx".into(),
                sha256: String::new(),
                bytes: 0,
            },
            tile_detector: None,
            config_file: "config.toml".into(),
        },
        config_toml: String::new(),
        frames: Vec::new(),
        gaps: Vec::new(),
        end: None,
        bad_lines: Vec::new(),
    };
    let review = Review::build(&flight, &[], true, None);
    let page = html::page(&review).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(page.matches("</script>").count(), 3);
    assert!(!page.contains("alert(1)</script>"));
    assert!(!review.flight.clean_end);
}

/// Issue 39 item 13: a flight over an autopilot reboot (its clock starts again from 0, and
/// after the reboot its stamps overlap those before it). Every report is timed and matched
/// (by the clock that survives the reboot where the autopilot's is ambiguous), the object
/// seen only before the reboot is reported, and a report that cannot be timed at all is
/// counted.
#[test]
fn a_flight_over_an_autopilot_reboot_is_timed_and_matched_throughout() {
    use crate::record::format::{GeoRecord, TrackRecord};
    use crate::track::{BBox, TrackOutput, TrackState};
    use nalgebra::Vector3;
    let origin = Geodetic::new(47.0, 8.0, 0.0).unwrap();
    let local = LocalTangentFrame::new(origin);
    // Boot 10 s before the flight, reboot at 30 s, 45 s in all, 10 fps.
    let stamp_us = |t: f64| -> u64 {
        let s = if t < 30.0 { 10.0 + t } else { t - 30.0 };
        (s * 1e6).round() as u64
    };
    // Object 1 is visible for the first 20 s only; object 2 all along.
    let at = |id: u32, t: f64| -> [f64; 2] {
        match id {
            1 => [40.0, 0.5 * t],
            _ => [-30.0 + 0.8 * t, 20.0],
        }
    };
    let dir = tempfile::tempdir().unwrap();
    let mut camera = String::from("frame,time_s,frame_stamp_us\n");
    let mut world = String::from("frame,time_s,id,class,lat_deg,lon_deg\n");
    let n = 450u64;
    for k in 0..n {
        let t = k as f64 / 10.0;
        camera.push_str(&format!("{},{t:.4},{}\n", k + 1, stamp_us(t)));
        for id in [1u32, 2] {
            if id == 1 && t >= 20.0 {
                continue;
            }
            let p = at(id, t);
            let g = local.to_geodetic(&Vector3::new(p[0], p[1], 0.0));
            world.push_str(&format!(
                "{},{t:.4},{id},swimmer,{:.9},{:.9}\n",
                k + 1,
                g.lat_deg,
                g.lon_deg
            ));
        }
    }
    std::fs::write(dir.path().join("camera.csv"), camera).unwrap();
    std::fs::write(dir.path().join("world.csv"), world).unwrap();
    let truth = Truth::load(dir.path()).unwrap();

    let report = |id: u64, p: [f64; 2]| {
        let g = local.to_geodetic(&Vector3::new(p[0], p[1], 0.0));
        TrackRecord {
            track: TrackOutput {
                id,
                bbox: BBox {
                    x: 0.0,
                    y: 0.0,
                    w: 10.0,
                    h: 10.0,
                },
                score: 0.9,
                class_id: 0,
                state: TrackState::Confirmed,
                world: None,
                detection_index: None,
                provisional: false,
            },
            geo: Some(GeoRecord {
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_m: 0.0,
                vel_n_mps: 0.0,
                vel_e_mps: 0.0,
                h_std_m: 1.0,
            }),
        }
    };
    // mgmot took every third frame; the autopilot is silent for 2 s over its reboot, so
    // frames there carry no autopilot time.
    let unix0 = 1_800_000_000_000_000u64;
    let mut frames = Vec::new();
    let mut reports = 0;
    for k in (0..n).step_by(3) {
        let t = k as f64 / 10.0;
        let silent = (30.0..32.0).contains(&t);
        let mut f = FrameRecord {
            time_s: t,
            autopilot_time_us: (!silent).then(|| stamp_us(t)),
            captured_unix_us: Some(unix0 + (t * 1e6).round() as u64),
            processed_unix_us: unix0 + (t * 1e6).round() as u64 + 50_000,
            ..FrameRecord::empty(k, 1280, 720)
        };
        if t < 20.0 {
            f.tracks.push(report(1, at(1, t)));
        }
        f.tracks.push(report(2, at(2, t)));
        reports += f.tracks.len();
        frames.push(f);
    }
    // A frame far outside the truth's run: no time in the truth by either clock.
    let mut stray = FrameRecord {
        time_s: 9_000.0,
        autopilot_time_us: None,
        captured_unix_us: Some(unix0 + 9_000_000_000),
        processed_unix_us: unix0 + 9_000_000_000,
        ..FrameRecord::empty(n + 1, 1280, 720)
    };
    stray.tracks.push(report(2, at(2, 44.0)));
    frames.push(stray);
    let t_of = |f: &FrameRecord| f.time_s;
    let r = truth.review(&frames, &Merges::of(&frames), &local, &t_of);
    assert_eq!(
        (r.matched, r.unmatched, r.untimed),
        (reports, 0, 1),
        "every report timed and matched but the stray one"
    );
    assert_eq!(r.objects.len(), 2);
    assert_eq!(
        r.objects[0].track_ids,
        [1],
        "the object seen before the reboot"
    );
    assert_eq!(r.objects[1].track_ids, [2]);
    assert!(r.overall.max_m < 0.05, "{:?}", r.overall);
}
