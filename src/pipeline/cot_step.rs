//! The Cursor-on-Target output of the frame step (`[outputs.cot]`): builds each frame's
//! events with the pure [`CotPublisher`] and queues them on the [`CotOutput`] task, which
//! never holds the frame up.

use super::telemetry::FramePose;
use crate::config::{CotSettings, Settings};
use crate::cot::{CotClock, CotOutput, CotPublisher, CotStats, PublisherSettings, VehicleFix};
use crate::frame::GeoFix;
use crate::geo::Geolocator;
use crate::report::TrackReport;
use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs};
use crate::track::{FrameOutput, TrackOutput};
use nalgebra::Vector3;
use serde::Serialize;
use std::sync::atomic::Ordering;

/// Border points per image edge of the camera footprint (16 in all: enough for the curve an
/// oblique view's range limit makes).
const FOOTPRINT_POINTS_PER_EDGE: usize = 4;

/// The CoT output's counters for `--stats-json`.
#[derive(Debug, Default, Clone, PartialEq, Eq, Serialize)]
pub struct CotCounters {
    /// Where the events went.
    pub endpoint: String,
    /// Events made and queued.
    pub events: u64,
    /// Events handed to the socket.
    pub sent: u64,
    /// Events replaced by a newer one of the same uid while the server was away.
    pub replaced: u64,
    /// Events dropped on a full queue.
    pub dropped: u64,
    /// UDP datagrams the socket refused.
    pub failed: u64,
    /// Connections made.
    pub connects: u64,
    /// Failed connection attempts and writes.
    pub errors: u64,
}

/// The CoT part of a frame step.
pub(super) struct CotStep {
    publisher: CotPublisher,
    output: CotOutput,
    vehicle: bool,
    events: u64,
    endpoint: String,
}

impl CotStep {
    /// Starts the output's task (on the current tokio runtime) when `[outputs.cot]` is on.
    pub fn start(settings: &Settings) -> Option<Self> {
        let cot: &CotSettings = settings.outputs.cot.as_ref()?;
        let system_id = settings.mavlink.system_id;
        let publisher_settings = PublisherSettings {
            every_us: u64::try_from(cot.every.as_micros()).unwrap_or(u64::MAX),
            stale_us: i64::try_from(cot.stale.as_micros()).unwrap_or(i64::MAX),
            types: cot.types.clone(),
            system_id,
            callsign: cot
                .callsign
                .clone()
                .unwrap_or_else(|| format!("mgmot-{system_id}")),
            run_tag: chrono::DateTime::from_timestamp_micros(crate::clock::unix_now_us())
                .unwrap_or_default()
                .format("%Y%m%dT%H%M%S")
                .to_string(),
        };
        let identity = CotPublisher::new(publisher_settings.clone());
        let output = CotOutput::spawn(
            cot,
            Box::new(move || identity.vehicle_message(None, crate::clock::unix_now_us())),
        );
        tracing::info!(
            endpoint = %cot.endpoint,
            rate_hz = 1.0 / cot.every.as_secs_f64(),
            "CoT output on"
        );
        Some(Self {
            publisher: CotPublisher::new(publisher_settings),
            output,
            vehicle: cot.vehicle,
            events: 0,
            endpoint: cot.endpoint.to_string(),
        })
    }

    /// Queues the due events of one frame. `fix` geolocates a track, `geolocator` (once the
    /// flight has a reference) gives the camera footprint, `tracker_us` is the tracker's clock, `delivered` when the frame arrived (the exposure time when the pose
    /// has none on the companion clock).
    #[allow(clippy::too_many_arguments)]
    pub fn frame(
        &mut self,
        output: &FrameOutput,
        size: (u32, u32),
        tracker_us: u64,
        pose: &FramePose,
        delivered: CompanionTimeUs,
        geolocator: Option<&Geolocator>,
        fix: &dyn Fn(&TrackOutput) -> Option<GeoFix>,
    ) {
        let now_unix_us = crate::clock::unix_now_us();
        let captured = pose.captured_at.unwrap_or(delivered);
        let age_us = i64::try_from(crate::clock::now().0.saturating_sub(captured.0)).unwrap_or(0);
        let clock = CotClock {
            tracker_us,
            observed_unix_us: now_unix_us - age_us,
            now_unix_us,
        };
        let stamp = pose.frame_time.unwrap_or(AutopilotTimeUs(0));
        let merged_from: std::collections::HashMap<u64, u64> = output
            .merges
            .iter()
            .map(|m| (m.merged_into_id, m.new_id))
            .collect();
        let reports: Vec<TrackReport> = output
            .tracks
            .iter()
            .map(|t| TrackReport::new(stamp, t, size, merged_from.get(&t.id).copied(), fix(t)))
            .collect();
        for m in self.publisher.frame(&reports, &output.merges, clock) {
            self.events += 1;
            self.output.send(m);
        }
        if self.vehicle {
            if let Ok(meta) = &pose.meta {
                let look = meta.camera_attitude * Vector3::new(0.0, 0.0, 1.0);
                let fix = VehicleFix {
                    lat_deg: meta.position.lat_deg,
                    lon_deg: meta.position.lon_deg,
                    alt_amsl_m: meta.position.alt_m,
                    heading_deg: Some(look.y.atan2(look.x).to_degrees()),
                };
                let ring: Vec<(f64, f64)> = geolocator
                    .and_then(|g| g.frame(meta).ok())
                    .map(|f| f.footprint(size, FOOTPRINT_POINTS_PER_EDGE))
                    .unwrap_or_default()
                    .iter()
                    .map(|p| (p.lat_deg, p.lon_deg))
                    .collect();
                for m in self.publisher.vehicle(&fix, &ring, clock) {
                    self.events += 1;
                    self.output.send(m);
                }
            }
        }
    }

    /// At the end of a run: waits up to 2 s for the queued events to be sent, closes the
    /// connection cleanly, says how many events were not sent, and returns the counters.
    pub fn finish(self) -> CotCounters {
        let Self {
            output,
            events,
            endpoint,
            ..
        } = self;
        let stats = output.shared_stats();
        let unsent = output.close(std::time::Duration::from_secs(2));
        if unsent > 0 {
            tracing::warn!(unsent, endpoint = %endpoint, "CoT: events not sent at exit");
        }
        counters_of(endpoint, events, &stats)
    }
}

/// The counters of an output that made `events` events.
fn counters_of(endpoint: String, events: u64, s: &CotStats) -> CotCounters {
    CotCounters {
        endpoint,
        events,
        sent: s.sent.load(Ordering::Relaxed),
        replaced: s.replaced.load(Ordering::Relaxed),
        dropped: s.dropped.load(Ordering::Relaxed),
        failed: s.failed.load(Ordering::Relaxed),
        connects: s.connects.load(Ordering::Relaxed),
        errors: s.errors.load(Ordering::Relaxed),
    }
}
