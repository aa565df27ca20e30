//! pymavlink, given the project's dialect XML, decodes what mgmot's encoders produce.
//! Needs python3 with pymavlink (scripts/requirements-test.txt; scripts/test.sh installs it
//! into `.venv`); fails, naming what is missing, if it is not there.

use crate::common;

use common::{repo_file, require_python, TestCommand, TestDir};
use mavlink_core::{MavHeader, MavlinkVersion};
use mgmot::frame::GeoFix;
use mgmot::geo::Geodetic;
use mgmot::mavlink::{heartbeat, mgmot_track, statustext, Severity};
use mgmot::report::TrackReport;
use mgmot::telemetry::AutopilotTimeUs;

#[test]
fn pymavlink_decodes_mgmot_messages() {
    let report = TrackReport {
        time: AutopilotTimeUs(123_456_789),
        track_id: 70_000,
        merged_from_id: Some(42),
        class_id: 2,
        confidence: 0.75,
        bbox_norm: [0.25, 0.5, 0.125, 0.0625],
        tracked: true,
        geo: Some(GeoFix {
            position: Geodetic {
                lat_deg: 47.6721234,
                lon_deg: 9.2679876,
                alt_m: 395.25,
            },
            vel_n_mps: 1.5,
            vel_e_mps: -2.0,
            h_std_m: 1.25,
            ce95_m: 2.2,
        }),
        provisional: false,
    };
    let header = MavHeader {
        system_id: 1,
        component_id: 191,
        sequence: 0,
    };
    let long = "mgmot: recording stopped: Input/output error (os error 5)";
    let id = std::num::NonZeroU16::new(9).unwrap();
    let mut bytes = Vec::new();
    let mut messages = vec![heartbeat(), mgmot_track(&report)];
    messages.extend(statustext(Severity::Warning, "mgmot: camera lost", id));
    messages.extend(statustext(Severity::Warning, long, id));
    for m in messages {
        mavlink_core::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, &m).unwrap();
    }
    require_python("pymavlink_decodes_mgmot_messages", &["pymavlink"]);
    let dir = TestDir::new();
    let frames = dir.write("frames.bin", bytes);
    let out = TestCommand::new("python3")
        .arg(repo_file("scripts/runtime_pymavlink_decode.py"))
        .arg(&frames)
        .output();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "pymavlink decode failed: {}{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    let msgs: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let types: Vec<&str> = msgs
        .iter()
        .map(|m| m["mavpackettype"].as_str().unwrap())
        .collect();
    assert_eq!(
        types,
        [
            "HEARTBEAT",
            "MGMOT_TRACK",
            "STATUSTEXT",
            "STATUSTEXT",
            "STATUSTEXT"
        ]
    );
    let t = &msgs[1];
    assert_eq!(t["track_id"], 70_000);
    assert_eq!(t["merged_from_id"], 42);
    assert_eq!(t["time_usec"], 123_456_789);
    assert_eq!(t["lat"], 476_721_234);
    assert_eq!(t["lon"], 92_679_876);
    assert_eq!(t["alt"], 395_250);
    assert_eq!(t["object_class"], 2);
    assert_eq!(t["flags"], 3);
    assert_eq!(t["vel_e"], -2.0);
    assert_eq!(t["h_std"], 1.25);
    assert_eq!(t["_srcComponent"], 191);
    assert_eq!(msgs[0]["type"], 18); // MAV_TYPE_ONBOARD_CONTROLLER
    assert_eq!(msgs[2]["text"], "mgmot: camera lost");
    assert_eq!(msgs[2]["id"], 0);
    // The long text in two chunks of one id, as a ground station reassembles them.
    assert_eq!(
        (&msgs[3]["id"], &msgs[3]["chunk_seq"]),
        (&9.into(), &0.into())
    );
    assert_eq!(
        (&msgs[4]["id"], &msgs[4]["chunk_seq"]),
        (&9.into(), &1.into())
    );
    let joined = format!(
        "{}{}",
        msgs[3]["text"].as_str().unwrap(),
        msgs[4]["text"].as_str().unwrap()
    );
    assert_eq!(joined, long);
}
