//! STATUSTEXT when something changes: each watched condition is reported when it is first
//! found broken and every time it changes after that, never on every frame.

use super::dialect::MavMessage;
use super::encode::{statustext, Severity};

/// Something whose loss and return mgmot announces to the operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Condition {
    /// Position telemetry from the autopilot (without it there is no geolocation).
    Telemetry,
    /// The frame source.
    Camera,
    /// The detector (a failing detector means no new detections).
    Detector,
}

impl Condition {
    /// The text when the condition breaks, before any detail.
    pub fn lost_text(self) -> &'static str {
        match self {
            Condition::Telemetry => "mgmot: no telemetry, geolocation invalid",
            Condition::Camera => "mgmot: camera lost",
            Condition::Detector => "mgmot: detector error",
        }
    }

    /// The text when it works again.
    pub fn back_text(self) -> &'static str {
        match self {
            Condition::Telemetry => "mgmot: telemetry ok",
            Condition::Camera => "mgmot: camera back",
            Condition::Detector => "mgmot: detector ok",
        }
    }
}

/// Turns observations of one [`Condition`] into STATUSTEXT on changes only. The first
/// observation is news only when it is bad ("ok" at start-up is not worth a message).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConditionReport {
    /// What is watched.
    condition: Condition,
    /// The last state seen; `None` before the first observation.
    ok: Option<bool>,
}

impl ConditionReport {
    /// Nothing observed yet.
    pub fn new(condition: Condition) -> Self {
        Self {
            condition,
            ok: None,
        }
    }

    /// Whether the last observation was good (`None` before the first).
    pub fn is_ok(&self) -> Option<bool> {
        self.ok
    }

    /// Records the current state; returns the STATUSTEXT to send when it is news. `detail`
    /// (e.g. the detector's error) is appended to a "lost" text; STATUSTEXT keeps the first 50
    /// bytes.
    pub fn observe(&mut self, ok: bool, detail: Option<&str>) -> Option<MavMessage> {
        let previous = self.ok.replace(ok);
        if previous == Some(ok) || (previous.is_none() && ok) {
            return None;
        }
        Some(if ok {
            statustext(Severity::Info, self.condition.back_text())
        } else {
            match detail {
                Some(d) => statustext(
                    Severity::Warning,
                    &format!("{}: {d}", self.condition.lost_text()),
                ),
                None => statustext(Severity::Warning, self.condition.lost_text()),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(m: Option<MavMessage>) -> Option<String> {
        match m {
            Some(MavMessage::STATUSTEXT(s)) => Some(s.text.to_str().unwrap().to_owned()),
            Some(other) => panic!("{other:?}"),
            None => None,
        }
    }

    #[test]
    fn only_changes_are_reported() {
        let mut r = ConditionReport::new(Condition::Detector);
        assert_eq!(text(r.observe(true, None)), None);
        assert_eq!(text(r.observe(true, None)), None);
        assert_eq!(
            text(r.observe(false, Some("model output has no boxes"))).as_deref(),
            Some("mgmot: detector error: model output has no boxes")
        );
        // Failing on every frame after that is not news.
        assert_eq!(text(r.observe(false, Some("again"))), None);
        assert_eq!(r.is_ok(), Some(false));
        assert_eq!(
            text(r.observe(true, None)).as_deref(),
            Some("mgmot: detector ok")
        );
        assert_eq!(text(r.observe(true, None)), None);
    }

    #[test]
    fn bad_at_start_is_news() {
        let mut r = ConditionReport::new(Condition::Telemetry);
        assert_eq!(
            text(r.observe(false, None)).as_deref(),
            Some("mgmot: no telemetry, geolocation invalid")
        );
        assert_eq!(
            text(r.observe(true, None)).as_deref(),
            Some("mgmot: telemetry ok")
        );
    }

    #[test]
    fn long_details_are_cut_to_fit() {
        let mut r = ConditionReport::new(Condition::Camera);
        let t = text(r.observe(false, Some(&"x".repeat(200)))).unwrap();
        assert_eq!(t.len(), 50);
        assert!(t.starts_with("mgmot: camera lost: x"));
    }
}
