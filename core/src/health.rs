//! Health of the runtime's inputs, for the operator: each watched condition (telemetry,
//! camera, detector) is announced when it is first found broken and every time it changes
//! after that, never on every frame. Pure: the runtime observes, the MAVLink edge sends the
//! [`Notice`] as STATUSTEXT and the log gets it too.

/// Something whose loss and return mgmot announces to the operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Condition {
    /// Position telemetry from the autopilot (without it there is no geolocation).
    Telemetry,
    /// Telemetry that cannot be true (refused by the pose gate; tracks are not moved by it).
    Plausibility,
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
            Condition::Plausibility => "mgmot: telemetry refused",
            Condition::Camera => "mgmot: camera lost",
            Condition::Detector => "mgmot: detector error",
        }
    }

    /// The text when it works again.
    pub fn back_text(self) -> &'static str {
        match self {
            Condition::Telemetry => "mgmot: telemetry ok",
            Condition::Plausibility => "mgmot: telemetry plausible again",
            Condition::Camera => "mgmot: camera back",
            Condition::Detector => "mgmot: detector ok",
        }
    }
}

/// How a [`Notice`] is to be shown (STATUSTEXT severity, log level).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// Something works (again).
    Info,
    /// Normal but significant: an object was found.
    Notice,
    /// Something is broken: the operator should know.
    Warning,
}

/// A change worth telling the operator about.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Notice {
    /// Info when a condition recovers, Warning when it breaks.
    pub level: Level,
    /// The text (the MAVLink edge sends more than 50 bytes as chunked STATUSTEXT, up to 200).
    pub text: String,
}

impl Notice {
    /// A notice with any text.
    pub fn new(level: Level, text: impl Into<String>) -> Self {
        Self {
            level,
            text: text.into(),
        }
    }
}

/// Turns observations of one [`Condition`] into [`Notice`]s on changes only. The first
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

    /// Records the current state; returns the notice to send when it is news. `detail`
    /// (e.g. the detector's error) is appended to a "lost" text.
    pub fn observe(&mut self, ok: bool, detail: Option<&str>) -> Option<Notice> {
        let previous = self.ok.replace(ok);
        if previous == Some(ok) || (previous.is_none() && ok) {
            return None;
        }
        Some(if ok {
            Notice::new(Level::Info, self.condition.back_text())
        } else {
            match detail {
                Some(d) => Notice::new(
                    Level::Warning,
                    format!("{}: {d}", self.condition.lost_text()),
                ),
                None => Notice::new(Level::Warning, self.condition.lost_text()),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(m: Option<Notice>) -> Option<String> {
        m.map(|n| n.text)
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
}
