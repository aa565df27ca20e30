//! How the review names things: class names, UTC times, degrees and minutes.

use crate::record::format::FrameRecord;

/// Class names by the tracker's class id (the ids of `MGMOT_OBJECT_CLASS`).
const CLASS_NAMES: [&str; 6] = [
    "unknown",
    "swimmer",
    "boat",
    "jetski",
    "life-saving appliance",
    "buoy",
];

/// The name of a tracker class id.
pub fn class_name(id: u32) -> &'static str {
    CLASS_NAMES.get(id as usize).copied().unwrap_or("unknown")
}

/// UTC (RFC 3339, milliseconds) of a time in µs since the UNIX epoch.
pub fn utc(unix_us: u64) -> String {
    let us = i64::try_from(unix_us).unwrap_or(i64::MAX);
    chrono::DateTime::from_timestamp_micros(us)
        .unwrap_or_default()
        .to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

/// A frame's time (µs since the UNIX epoch): its exposure when mapped, else when processed.
pub fn frame_unix_us(f: &FrameRecord) -> u64 {
    f.captured_unix_us.unwrap_or(f.processed_unix_us)
}

/// Degrees as D°M.mmm' with a hemisphere letter (`pos`/`neg`: "N"/"S" or "E"/"W").
pub fn dm(deg: f64, pos: char, neg: char) -> String {
    let h = if deg < 0.0 { neg } else { pos };
    let a = deg.abs();
    let mut d = a.trunc();
    let mut m = (a - d) * 60.0;
    // 59.9996' rounds to 60.000': carry it into the degrees.
    if (m * 1000.0).round() >= 60_000.0 {
        d += 1.0;
        m = 0.0;
    }
    format!("{d:.0}°{m:06.3}'{h}")
}
