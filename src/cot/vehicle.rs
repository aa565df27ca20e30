//! A drone and its camera footprint as CoT events: the same shape whether `mgmot run` sends its
//! own drone or `mgmot ground` sends every drone it hears.

use super::event::{event_xml, Detail, Envelope, Point, UNKNOWN};
use super::{CotMessage, VEHICLE_TYPE};

/// The vehicle's own position, for its event.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleFix {
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Altitude above mean sea level (m).
    pub alt_amsl_m: f64,
    /// Heading (degrees, 0 north, clockwise); `None` when unknown.
    pub heading_deg: Option<f64>,
}

/// Who a drone is on the map.
#[derive(Debug, Clone, Copy)]
pub struct VehicleId<'a> {
    /// Its event's uid (its footprint's is `<uid>.footprint`).
    pub uid: &'a str,
    /// Its callsign.
    pub callsign: &'a str,
    /// Its MAVLink system id.
    pub system_id: u8,
}

/// The drone's event (`a-f-A-M-H-Q`, how `m-g`) at `now_us`, valid for `stale_for_us`;
/// without a fix it is an identity only (at 0, 0 with unknown errors, stale at once), which a
/// TAK server takes as the connection's identity.
pub fn vehicle_event(
    id: VehicleId<'_>,
    fix: Option<&VehicleFix>,
    now_us: i64,
    stale_for_us: i64,
) -> CotMessage {
    let (point, stale_us) = match fix {
        Some(f) => (
            Point {
                lat_deg: f.lat_deg,
                lon_deg: f.lon_deg,
                hae_m: UNKNOWN,
                ce_m: UNKNOWN,
                le_m: UNKNOWN,
            },
            now_us + stale_for_us,
        ),
        None => (Point::unknown(), now_us),
    };
    let mut detail = Detail::new()
        .element("contact", &[("callsign", Some(id.callsign.to_owned()))])
        .element(
            "mgmot",
            &[
                ("role", Some("vehicle".to_owned())),
                ("system_id", Some(id.system_id.to_string())),
                (
                    "alt_amsl",
                    fix.filter(|f| f.alt_amsl_m.is_finite())
                        .map(|f| format!("{:.1}", f.alt_amsl_m)),
                ),
            ],
        );
    if let Some(h) = fix.and_then(|f| f.heading_deg) {
        detail = detail.element(
            "track",
            &[
                ("course", Some(format!("{:.1}", h.rem_euclid(360.0)))),
                ("speed", Some("0.0".to_owned())),
            ],
        );
    }
    let xml = event_xml(
        &Envelope {
            uid: id.uid,
            cot_type: VEHICLE_TYPE,
            how: "m-g",
            time_us: now_us,
            start_us: now_us,
            stale_us,
            point,
        },
        &detail.into_xml(),
    );
    CotMessage {
        uid: id.uid.into(),
        xml: xml.into(),
    }
}

/// The drone's camera footprint as a TAK drawing (`u-d-f`, a closed line through
/// `<link point>`s, uid `<vehicle uid>.footprint`, at the ring's centroid). `ring` is
/// (lat, lon) in degrees, at least three points; `start_us` when the camera looked there.
pub fn footprint_event(
    id: VehicleId<'_>,
    ring: &[(f64, f64)],
    start_us: i64,
    now_us: i64,
    stale_for_us: i64,
) -> CotMessage {
    let uid = format!("{}.footprint", id.uid);
    let n = ring.len().max(1) as f64;
    let (lat, lon) = ring
        .iter()
        .fold((0.0, 0.0), |(a, b), (la, lo)| (a + la / n, b + lo / n));
    let mut detail = Detail::new().element(
        "contact",
        &[("callsign", Some(format!("{} camera", id.callsign)))],
    );
    for (la, lo) in ring.iter().chain(ring.first()) {
        detail = detail.element("link", &[("point", Some(format!("{la:.7},{lo:.7}")))]);
    }
    let detail = detail
        .element("strokeColor", &[("value", Some("-256".to_owned()))])
        .element("strokeWeight", &[("value", Some("2.0".to_owned()))])
        .element("fillColor", &[("value", Some("436207360".to_owned()))])
        .element("labels_on", &[("value", Some("false".to_owned()))])
        .element(
            "mgmot",
            &[
                ("role", Some("footprint".to_owned())),
                ("system_id", Some(id.system_id.to_string())),
            ],
        )
        .into_xml();
    let xml = event_xml(
        &Envelope {
            uid: &uid,
            cot_type: "u-d-f",
            how: "m-i",
            time_us: now_us,
            start_us: start_us.min(now_us),
            stale_us: now_us + stale_for_us,
            point: Point {
                lat_deg: lat,
                lon_deg: lon,
                hae_m: UNKNOWN,
                ce_m: UNKNOWN,
                le_m: UNKNOWN,
            },
        },
        &detail,
    );
    CotMessage {
        uid: uid.into(),
        xml: xml.into(),
    }
}
