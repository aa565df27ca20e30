//! Telemetry health from `flight.tlog` and the frame record: message rates, gaps in the
//! autopilot's stream, the TIMESYNC offset over time and the frames dropped.

use crate::mavlink::dialect::MavMessage;
use crate::record::format::FrameRecord;
use crate::record::tlog::TlogEntry;
use mavlink_core::{MavlinkVersion, Message};
use serde::Serialize;
use std::collections::BTreeMap;

/// A silence of the autopilot longer than this (s) is a gap.
pub const GAP_S: f64 = 1.0;

/// Messages of one type from one sender.
#[derive(Debug, Clone, Serialize)]
pub struct Rate {
    /// `autopilot`, `mgmot` or `sys S comp C`.
    pub from: String,
    /// The message's name (`#ID` when this dialect does not know it).
    pub name: String,
    /// Packets.
    pub count: u64,
    /// Average rate over the tlog's span (Hz).
    pub rate_hz: f64,
}

/// A silence of the autopilot.
#[derive(Debug, Clone, Serialize)]
pub struct Gap {
    /// Start (s since the first frame).
    pub t: f64,
    /// Length (s).
    pub duration_s: f64,
}

/// One TIMESYNC round trip.
#[derive(Debug, Clone, Serialize)]
pub struct Timesync {
    /// When the answer arrived (s since the first frame).
    pub t: f64,
    /// The autopilot's clock minus mgmot's (ms), at the middle of the round trip.
    pub offset_ms: f64,
    /// Round trip (ms).
    pub rtt_ms: f64,
}

/// Telemetry health.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Health {
    /// Packets in the tlog.
    pub packets: usize,
    /// Whether the tlog ended cleanly.
    pub tlog_clean: bool,
    /// Span of the tlog (s).
    pub tlog_span_s: f64,
    /// Packets that did not decode.
    pub undecoded: u64,
    /// Per sender and message type.
    pub rates: Vec<Rate>,
    /// Silences of the autopilot longer than [`GAP_S`].
    pub gaps: Vec<Gap>,
    /// TIMESYNC round trips.
    pub timesync: Vec<Timesync>,
    /// Frames dropped so far, per frame: (s since the first frame, count).
    pub dropped: Vec<(f64, u64)>,
    /// Frames dropped in all.
    pub dropped_total: u64,
}

/// The payload of a packet (MAVLink 1 or 2).
fn decode(e: &TlogEntry) -> Option<MavMessage> {
    let p = &e.packet;
    let (version, start) = match p.first()? {
        0xFD => (MavlinkVersion::V2, 10),
        _ => (MavlinkVersion::V1, 6),
    };
    let len = usize::from(*p.get(1)?);
    let payload = p.get(start..start + len)?;
    MavMessage::parse(version, e.message_id(), payload).ok()
}

impl Health {
    /// From the frames and the tlog; `system_id`/`autopilot_component` name the autopilot,
    /// `own_component` mgmot; times are relative to `t0_us` (µs since the UNIX epoch).
    pub fn of(
        frames: &[FrameRecord],
        tlog: &[TlogEntry],
        tlog_clean: bool,
        system_id: u8,
        autopilot_component: u8,
        own_component: u8,
        t0_us: u64,
    ) -> Self {
        let t = |us: u64| (us as f64 - t0_us as f64) / 1e6;
        let span_s = match (tlog.first(), tlog.last()) {
            (Some(a), Some(b)) => (b.unix_us.saturating_sub(a.unix_us)) as f64 / 1e6,
            _ => 0.0,
        };
        let mut counts: BTreeMap<(String, String), u64> = BTreeMap::new();
        let mut undecoded = 0;
        let mut gaps = Vec::new();
        let mut last_autopilot: Option<u64> = None;
        // mgmot's open requests: its ts1 -> when sent.
        let mut requests: BTreeMap<i64, u64> = BTreeMap::new();
        let mut timesync = Vec::new();
        for e in tlog {
            let from_autopilot =
                e.system_id() == system_id && e.component_id() == autopilot_component;
            let from_mgmot = e.system_id() == system_id && e.component_id() == own_component;
            let message = decode(e);
            if message.is_none() {
                undecoded += 1;
            }
            let from = match (from_autopilot, from_mgmot) {
                (true, _) => "autopilot".to_owned(),
                (_, true) => "mgmot".to_owned(),
                _ => format!("sys {} comp {}", e.system_id(), e.component_id()),
            };
            let name = message.as_ref().map_or_else(
                || format!("#{}", e.message_id()),
                |m| m.message_name().to_owned(),
            );
            *counts.entry((from, name)).or_insert(0) += 1;
            if from_autopilot {
                if let Some(prev) = last_autopilot {
                    let d = e.unix_us.saturating_sub(prev) as f64 / 1e6;
                    if d > GAP_S {
                        gaps.push(Gap {
                            t: t(prev),
                            duration_s: d,
                        });
                    }
                }
                last_autopilot = Some(e.unix_us);
            }
            if let Some(MavMessage::TIMESYNC(ts)) = &message {
                if from_mgmot && ts.tc1 == 0 {
                    requests.insert(ts.ts1, e.unix_us);
                } else if from_autopilot && ts.tc1 != 0 {
                    if let Some(sent_us) = requests.remove(&ts.ts1) {
                        let rtt_ns = e.unix_us.saturating_sub(sent_us) as f64 * 1e3;
                        // mgmot's clock at the answer: its request's stamp plus the round
                        // trip (as the tlog's clock measured it).
                        let offset_ns = ts.tc1 as f64 - (ts.ts1 as f64 + rtt_ns / 2.0);
                        timesync.push(Timesync {
                            t: t(e.unix_us),
                            offset_ms: offset_ns / 1e6,
                            rtt_ms: rtt_ns / 1e6,
                        });
                    }
                }
            }
        }
        let rates = counts
            .into_iter()
            .map(|((from, name), count)| Rate {
                from,
                name,
                count,
                rate_hz: if span_s > 0.0 {
                    count as f64 / span_s
                } else {
                    0.0
                },
            })
            .collect();
        let dropped: Vec<(f64, u64)> = frames
            .iter()
            .map(|f| (t(super::frame_unix_us(f)), f.frames_dropped))
            .collect();
        Self {
            packets: tlog.len(),
            tlog_clean,
            tlog_span_s: span_s,
            undecoded,
            rates,
            gaps,
            timesync,
            dropped_total: frames.last().map_or(0, |f| f.frames_dropped),
            dropped,
        }
    }
}
