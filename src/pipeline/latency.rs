//! Per-stage latency histograms of the runtime (HdrHistogram), logged every
//! [`LOG_INTERVAL`] for the interval just ended and summarised over the whole run at exit.
//!
//! Stages, in the order a frame meets them ([`Stage`]): its age when inference takes it
//! (capture timestamp -> slot), the detector (and within it the model run alone), pose lookup
//! and geolocation, the tracker, building and queueing the outputs, the whole inference-thread
//! work of the frame, the wait in the link's queue until the socket has the message, and end to
//! end: the frame's capture timestamp to the moment its MGMOT_TRACK is handed to the socket.

use hdrhistogram::Histogram;
use serde::Serialize;
use std::time::Duration;

/// How often the runtime logs the histograms of the interval just ended.
pub const LOG_INTERVAL: Duration = Duration::from_secs(10);

/// Largest latency recorded exactly (µs): one minute. Longer values (a stalled source) are
/// recorded as one minute, so the maximum still shows that something stalled.
const MAX_TRACKABLE_US: u64 = 60_000_000;

/// Significant decimal digits kept per value: 0.1 % resolution at any magnitude, with a fixed
/// footprint (about 200 KB per histogram), so the histograms never grow.
const SIGNIFICANT_DIGITS: u8 = 3;

/// A measured stretch of the pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Capture timestamp -> taken by the inference thread: the source's own latency, the
    /// transfer and the wait in the newest-frame slot. Needs the capture time on the
    /// companion clock (for simulator frames: once the autopilot clock is mapped).
    FrameAge,
    /// Delivered by the frame source to the capture thread -> taken by the inference thread:
    /// the wait in the newest-frame slot.
    SlotWait,
    /// The detector call (pre-processing, model, post-processing).
    Detect,
    /// The model run alone, when the detector reports it.
    DetectInference,
    /// Pose interpolation at the frame time and geolocation of every detection.
    PoseGeolocate,
    /// One tracker step.
    Track,
    /// Building MGMOT_TRACK / TARGET_ABSOLUTE and queueing them for the link.
    Encode,
    /// The whole inference-thread work of one frame: taken from the slot -> outputs queued.
    Processing,
    /// Queued -> handed to the socket (the link's sender task).
    Send,
    /// Delivered by the frame source -> MGMOT_TRACK handed to the socket, one value per
    /// message: mgmot's own latency, whatever the source's.
    DeliveredToSocket,
    /// Capture timestamp -> MGMOT_TRACK handed to the socket, one value per message.
    EndToEnd,
}

impl Stage {
    /// Every stage, in pipeline order.
    pub const ALL: [Stage; 11] = [
        Stage::FrameAge,
        Stage::SlotWait,
        Stage::Detect,
        Stage::DetectInference,
        Stage::PoseGeolocate,
        Stage::Track,
        Stage::Encode,
        Stage::Processing,
        Stage::Send,
        Stage::DeliveredToSocket,
        Stage::EndToEnd,
    ];

    /// The name used in logs and in the stats JSON.
    pub fn name(self) -> &'static str {
        match self {
            Stage::FrameAge => "frame_age",
            Stage::SlotWait => "slot_wait",
            Stage::Detect => "detect",
            Stage::DetectInference => "detect_inference",
            Stage::PoseGeolocate => "pose_geolocate",
            Stage::Track => "track",
            Stage::Encode => "encode",
            Stage::Processing => "processing",
            Stage::Send => "send",
            Stage::DeliveredToSocket => "delivered_to_socket",
            Stage::EndToEnd => "end_to_end",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// Percentiles of one stage, in microseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct StageSummary {
    /// Values recorded.
    pub count: u64,
    /// Mean.
    pub mean_us: u64,
    /// Median.
    pub p50_us: u64,
    /// 95th percentile.
    pub p95_us: u64,
    /// 99th percentile.
    pub p99_us: u64,
    /// Largest value.
    pub max_us: u64,
}

/// The summaries of every stage that recorded something. Serialises as a map from stage name
/// to [`StageSummary`], in pipeline order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LatencyReport {
    /// By stage name, in pipeline order.
    pub stages: Vec<(&'static str, StageSummary)>,
}

impl Serialize for LatencyReport {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = serializer.serialize_map(Some(self.stages.len()))?;
        for (name, summary) in &self.stages {
            map.serialize_entry(name, summary)?;
        }
        map.end()
    }
}

impl LatencyReport {
    /// The summary of one stage, if it recorded anything.
    pub fn get(&self, stage: Stage) -> Option<&StageSummary> {
        self.stages
            .iter()
            .find(|(name, _)| *name == stage.name())
            .map(|(_, s)| s)
    }

    /// One line for the log: `stage p50/p95/p99/max ms (n)` per stage.
    pub fn to_log_line(&self) -> String {
        let ms = |us: u64| us as f64 / 1000.0;
        self.stages
            .iter()
            .map(|(name, s)| {
                format!(
                    "{name} {:.1}/{:.1}/{:.1}/{:.1} ms (n={})",
                    ms(s.p50_us),
                    ms(s.p95_us),
                    ms(s.p99_us),
                    ms(s.max_us),
                    s.count
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// Histograms per stage for the current log interval and for the whole run.
#[derive(Debug, Clone)]
pub struct Latency {
    window: Vec<Histogram<u64>>,
    total: Vec<Histogram<u64>>,
}

impl Default for Latency {
    fn default() -> Self {
        Self::new()
    }
}

fn empty_histogram() -> Histogram<u64> {
    // Constant bounds inside hdrhistogram's documented limits (low >= 1, high >= 2 * low,
    // digits <= 5); no input reaches this, and `bounds_are_valid` checks it.
    Histogram::new_with_bounds(1, MAX_TRACKABLE_US, SIGNIFICANT_DIGITS)
        .expect("constant histogram bounds are valid")
}

impl Latency {
    /// Empty histograms.
    pub fn new() -> Self {
        let make = || Stage::ALL.iter().map(|_| empty_histogram()).collect();
        Self {
            window: make(),
            total: make(),
        }
    }

    /// Records one value of `stage`.
    pub fn record(&mut self, stage: Stage, value: Duration) {
        let us = u64::try_from(value.as_micros())
            .unwrap_or(u64::MAX)
            .clamp(1, MAX_TRACKABLE_US);
        let i = stage.index();
        self.window[i].saturating_record(us);
        self.total[i].saturating_record(us);
    }

    /// Records `to - from` in microseconds of one clock; nothing when `to` is before `from`
    /// (a clock mapping that moved).
    pub fn record_between_us(&mut self, stage: Stage, from_us: u64, to_us: u64) {
        if let Some(d) = to_us.checked_sub(from_us) {
            self.record(stage, Duration::from_micros(d));
        }
    }

    /// The interval since the last call (or the start), and starts a new one.
    pub fn take_window(&mut self) -> LatencyReport {
        let report = summarise(&self.window);
        for h in &mut self.window {
            h.reset();
        }
        report
    }

    /// The whole run so far.
    pub fn total(&self) -> LatencyReport {
        summarise(&self.total)
    }
}

fn summarise(histograms: &[Histogram<u64>]) -> LatencyReport {
    LatencyReport {
        stages: Stage::ALL
            .iter()
            .zip(histograms)
            .filter(|(_, h)| !h.is_empty())
            .map(|(stage, h)| {
                (
                    stage.name(),
                    StageSummary {
                        count: h.len(),
                        mean_us: h.mean().round() as u64,
                        p50_us: h.value_at_quantile(0.50),
                        p95_us: h.value_at_quantile(0.95),
                        p99_us: h.value_at_quantile(0.99),
                        max_us: h.max(),
                    },
                )
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_valid() {
        assert!(Histogram::<u64>::new_with_bounds(1, MAX_TRACKABLE_US, SIGNIFICANT_DIGITS).is_ok());
    }

    #[test]
    fn percentiles_of_a_known_distribution() {
        let mut l = Latency::new();
        for ms in 1..=100u64 {
            l.record(Stage::Detect, Duration::from_millis(ms));
        }
        let r = l.total();
        let s = r.get(Stage::Detect).unwrap();
        assert_eq!(s.count, 100);
        // 0.1 % resolution: each percentile is within one part in a thousand.
        let close = |got: u64, want: u64| (got as f64 - want as f64).abs() <= want as f64 * 1e-3;
        assert!(close(s.p50_us, 50_000), "{s:?}");
        assert!(close(s.p95_us, 95_000), "{s:?}");
        assert!(close(s.p99_us, 99_000), "{s:?}");
        assert!(close(s.max_us, 100_000), "{s:?}");
        assert!(close(s.mean_us, 50_500), "{s:?}");
        assert!(
            r.get(Stage::Track).is_none(),
            "stages without values are left out"
        );
    }

    #[test]
    fn window_resets_but_total_keeps() {
        let mut l = Latency::new();
        l.record(Stage::Track, Duration::from_micros(300));
        assert_eq!(l.take_window().get(Stage::Track).unwrap().count, 1);
        assert!(l.take_window().stages.is_empty());
        l.record(Stage::Track, Duration::from_micros(500));
        assert_eq!(l.take_window().get(Stage::Track).unwrap().count, 1);
        assert_eq!(l.total().get(Stage::Track).unwrap().count, 2);
    }

    #[test]
    fn out_of_range_values_saturate_and_reversed_intervals_are_skipped() {
        let mut l = Latency::new();
        l.record(Stage::EndToEnd, Duration::from_secs(3600));
        l.record(Stage::EndToEnd, Duration::ZERO);
        l.record_between_us(Stage::FrameAge, 2_000, 1_000);
        let r = l.total();
        let s = r.get(Stage::EndToEnd).unwrap();
        assert_eq!(s.count, 2);
        assert!(s.max_us >= MAX_TRACKABLE_US * 999 / 1000);
        assert!(r.get(Stage::FrameAge).is_none());
    }

    #[test]
    fn log_line_names_every_recorded_stage() {
        let mut l = Latency::new();
        l.record(Stage::Detect, Duration::from_millis(12));
        l.record(Stage::EndToEnd, Duration::from_millis(40));
        let line = l.total().to_log_line();
        assert!(
            line.contains("detect 12.0/12.0/12.0/12.0 ms (n=1)"),
            "{line}"
        );
        assert!(line.contains("end_to_end 40.0/"), "{line}");
        let json = serde_json::to_value(l.total()).unwrap();
        let p50 = json["detect"]["p50_us"].as_u64().unwrap();
        assert!((12_000..=12_012).contains(&p50), "0.1 % resolution: {p50}");
        assert_eq!(json["end_to_end"]["count"], 1);
    }
}
