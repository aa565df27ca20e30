//! Cursor-on-Target (CoT) event XML: the base schema's `<event>` with its `<point>` and a
//! `<detail>`, as TAK clients (ATAK, WinTAK, iTAK) and TAK servers read it. Pure: the values
//! come in, a string goes out.
//!
//! The base schema (MITRE's CoT `Event.xsd`, version 2.0) requires on `<event>` the attributes
//! `version`, `uid`, `type`, `time`, `start`, `stale` and `how`, and on `<point>` `lat`, `lon`,
//! `hae`, `ce` and `le`; times are `xs:dateTime` in UTC (`2026-12-06T15:30:00.123Z`), a
//! distance that is unknown is `9999999.0`.

use std::fmt::Write as _;

/// What CoT writes for an unknown height or error.
pub const UNKNOWN: f64 = 9_999_999.0;

/// A time as CoT writes it: UTC, milliseconds, `Z` (`2026-12-06T15:30:00.123Z`). `unix_us` is
/// microseconds since the Unix epoch; a time outside chrono's range is written as the epoch.
pub fn format_time(unix_us: i64) -> String {
    chrono::DateTime::from_timestamp_micros(unix_us)
        .unwrap_or_default()
        .format("%Y-%m-%dT%H:%M:%S%.3fZ")
        .to_string()
}

/// The point of an event.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Latitude, degrees (WGS84).
    pub lat_deg: f64,
    /// Longitude, degrees (WGS84).
    pub lon_deg: f64,
    /// Height above the WGS84 ellipsoid (m), or [`UNKNOWN`].
    pub hae_m: f64,
    /// Circular error (m): the radius around the point that holds it (mgmot: at 95 %).
    pub ce_m: f64,
    /// Linear (vertical) error (m), or [`UNKNOWN`].
    pub le_m: f64,
}

impl Point {
    /// A point whose position is not known (a placeholder for identity events): 0, 0 with
    /// unknown errors.
    pub fn unknown() -> Self {
        Self {
            lat_deg: 0.0,
            lon_deg: 0.0,
            hae_m: UNKNOWN,
            ce_m: UNKNOWN,
            le_m: UNKNOWN,
        }
    }
}

/// The envelope of one event: everything but the detail.
#[derive(Debug, Clone, PartialEq)]
pub struct Envelope<'a> {
    /// Unique id of the thing the event is about; later events with the same uid update it.
    pub uid: &'a str,
    /// CoT type (`a-n-G`, `a-f-A-M-H-Q`, `t-x-d-d`, ...).
    pub cot_type: &'a str,
    /// How the position was obtained (`m-i`: machine, from imagery; `m-g`: machine, GPS).
    pub how: &'a str,
    /// When the event was made (µs since the Unix epoch).
    pub time_us: i64,
    /// Start of its validity (µs).
    pub start_us: i64,
    /// End of its validity: a map greys out or drops the thing after it (µs).
    pub stale_us: i64,
    /// Where.
    pub point: Point,
}

/// An event: the envelope and the inner XML of its `<detail>` (built with [`Detail`]).
pub fn event_xml(e: &Envelope<'_>, detail: &str) -> String {
    let mut s = String::with_capacity(400 + detail.len());
    s.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>");
    let _ = write!(
        s,
        "<event version=\"2.0\" uid=\"{}\" type=\"{}\" how=\"{}\" time=\"{}\" start=\"{}\" stale=\"{}\">",
        escape(e.uid),
        escape(e.cot_type),
        escape(e.how),
        format_time(e.time_us),
        format_time(e.start_us),
        format_time(e.stale_us),
    );
    let p = &e.point;
    let _ = write!(
        s,
        "<point lat=\"{:.7}\" lon=\"{:.7}\" hae=\"{}\" ce=\"{}\" le=\"{}\"/>",
        p.lat_deg,
        p.lon_deg,
        distance(p.hae_m),
        distance(p.ce_m),
        distance(p.le_m),
    );
    let _ = write!(s, "<detail>{detail}</detail></event>");
    s
}

/// A distance attribute: one decimal, or [`UNKNOWN`] for a value that is not finite.
fn distance(v: f64) -> String {
    if v.is_finite() {
        format!("{:.1}", v.clamp(-UNKNOWN, UNKNOWN))
    } else {
        format!("{UNKNOWN:.1}")
    }
}

/// Builds the inner XML of a `<detail>`: empty elements with attributes, and text elements.
#[derive(Debug, Default, Clone)]
pub struct Detail {
    xml: String,
}

impl Detail {
    /// An empty detail.
    pub fn new() -> Self {
        Self::default()
    }

    /// `<name a="v" .../>`; attributes whose value is `None` are left out.
    pub fn element(mut self, name: &str, attributes: &[(&str, Option<String>)]) -> Self {
        let _ = write!(self.xml, "<{name}");
        for (k, v) in attributes {
            if let Some(v) = v {
                let _ = write!(self.xml, " {k}=\"{}\"", escape(v));
            }
        }
        self.xml.push_str("/>");
        self
    }

    /// `<name>text</name>`.
    pub fn text(mut self, name: &str, text: &str) -> Self {
        let _ = write!(self.xml, "<{name}>{}</{name}>", escape(text));
        self
    }

    /// The inner XML.
    pub fn into_xml(self) -> String {
        self.xml
    }
}

/// XML-escapes text for an attribute value or element content. Characters XML 1.0 does not
/// allow (most control characters) are dropped.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\t' | '\n' | '\r' => out.push(c),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => {}
            c => out.push(c),
        }
    }
    out
}

/// A delete event (`t-x-d-d`) for `uid`: TAK clients remove the thing at once instead of
/// waiting for it to go stale. `by_uid` is who deletes it (the vehicle).
pub fn delete_xml(uid: &str, by_uid: &str, time_us: i64) -> String {
    let detail = Detail::new()
        .element(
            "link",
            &[
                ("uid", Some(uid.to_owned())),
                ("relation", Some("none".to_owned())),
                ("type", Some("none".to_owned())),
            ],
        )
        .element("__forcedelete", &[])
        .into_xml();
    event_xml(
        &Envelope {
            uid: by_uid,
            cot_type: "t-x-d-d",
            how: "m-g",
            time_us,
            start_us: time_us,
            stale_us: time_us + 20_000_000,
            point: Point::unknown(),
        },
        &detail,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_utc_with_milliseconds() {
        assert_eq!(format_time(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(
            format_time(1_796_571_000_123_456),
            "2026-12-06T15:30:00.123Z"
        );
    }

    #[test]
    fn an_event_has_every_required_attribute() {
        let xml = event_xml(
            &Envelope {
                uid: "a&b",
                cot_type: "a-n-G",
                how: "m-i",
                time_us: 0,
                start_us: 0,
                stale_us: 60_000_000,
                point: Point {
                    lat_deg: 47.123_456_78,
                    lon_deg: -9.5,
                    hae_m: f64::NAN,
                    ce_m: 3.25,
                    le_m: UNKNOWN,
                },
            },
            &Detail::new()
                .element("contact", &[("callsign", Some("swimmer <7>".into()))])
                .text("remarks", "a \"b\"")
                .into_xml(),
        );
        assert!(xml.contains("uid=\"a&amp;b\""), "{xml}");
        assert!(xml.contains("stale=\"1970-01-01T00:01:00.000Z\""), "{xml}");
        assert!(
            xml.contains("<point lat=\"47.1234568\" lon=\"-9.5000000\" hae=\"9999999.0\" ce=\"3.2\" le=\"9999999.0\"/>")
                || xml.contains("ce=\"3.3\""),
            "{xml}"
        );
        assert!(xml.contains("callsign=\"swimmer &lt;7&gt;\""), "{xml}");
        assert!(xml.contains("<remarks>a &quot;b&quot;</remarks>"), "{xml}");
        assert!(xml.ends_with("</detail></event>"));
    }

    #[test]
    fn escaping_drops_characters_xml_forbids() {
        assert_eq!(escape("a\u{1}b\tc'"), "ab\tc&apos;");
    }

    #[test]
    fn a_delete_names_the_deleted_uid() {
        let xml = delete_xml("mgmot.1.x.7", "mgmot.1.x", 1_000_000);
        assert!(xml.contains("type=\"t-x-d-d\""));
        assert!(xml.contains("<link uid=\"mgmot.1.x.7\" relation=\"none\" type=\"none\"/>"));
        assert!(xml.contains("<__forcedelete/>"));
    }
}
