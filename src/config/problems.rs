//! What validation reports: each [`Problem`] under its dotted key, all of them collected by
//! [`Problems`] rather than the first alone.

use std::time::Duration;

/// One invalid value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{key}`: {problem}")]
pub struct Problem {
    /// Dotted key, e.g. `mavlink.connection`.
    pub key: String,
    /// What is wrong with it.
    pub problem: String,
}

/// The problems found so far by a validation, in the order they were found.
#[derive(Debug, Default)]
pub struct Problems {
    /// Every problem, in the order found.
    list: Vec<Problem>,
}

impl Problems {
    /// Records that `key` is wrong.
    pub fn push(&mut self, key: &str, problem: impl Into<String>) {
        self.list.push(Problem {
            key: key.to_owned(),
            problem: problem.into(),
        });
    }

    /// True when nothing was found.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// How many problems were found so far.
    pub fn len(&self) -> usize {
        self.list.len()
    }

    /// The problems, never an empty list: a section that refused without naming a problem is
    /// a bug, still reported rather than taken for a valid configuration.
    pub fn into_vec(mut self) -> Vec<Problem> {
        if self.list.is_empty() {
            self.push("config", "refused without a named problem (a bug in mgmot)");
        }
        self.list
    }

    /// `v` if it is a number in `(lo, hi]`. Every rate, duration and noise figure has an upper
    /// bound: beyond it a value is a typo (1e300 Hz, a 30-year timeout) that would overflow a
    /// timer or a covariance.
    pub fn within_open(&mut self, key: &str, v: f64, lo: f64, hi: f64) -> Option<f64> {
        self.within(key, v, lo, hi, true)
    }

    /// `v` if it is a number in `[lo, hi]` (see [`Problems::within_open`]).
    pub fn within_closed(&mut self, key: &str, v: f64, lo: f64, hi: f64) -> Option<f64> {
        self.within(key, v, lo, hi, false)
    }

    fn within(&mut self, key: &str, v: f64, lo: f64, hi: f64, lo_open: bool) -> Option<f64> {
        let above_lo = if lo_open { v > lo } else { v >= lo };
        if v.is_finite() && above_lo && v <= hi {
            return Some(v);
        }
        let open = if lo_open { "(" } else { "[" };
        self.push(
            key,
            format!("must be a number in {open}{lo}, {hi}], got {v}"),
        );
        None
    }

    /// `Some(v)` when `ok`, else the problem under `key`.
    pub fn check<T>(&mut self, ok: bool, key: &str, problem: impl Into<String>, v: T) -> Option<T> {
        if ok {
            Some(v)
        } else {
            self.push(key, problem);
            None
        }
    }
}

/// `ms` milliseconds as a duration (`ms` already checked to be finite, >= 0 and bounded;
/// anything else is reported under `key` rather than panicking).
pub(super) fn millis(p: &mut Problems, key: &str, ms: f64) -> Option<Duration> {
    let d = Duration::try_from_secs_f64(ms / 1000.0);
    p.check(d.is_ok(), key, format!("is no duration: {ms} ms"), d.ok())
        .flatten()
}

/// The period of a rate in Hz (`hz` already checked to be finite and > 0).
pub(super) fn period(p: &mut Problems, key: &str, hz: f64) -> Option<Duration> {
    let d = Duration::try_from_secs_f64(1.0 / hz);
    p.check(d.is_ok(), key, format!("gives no period: {hz} Hz"), d.ok())
        .flatten()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collects_every_problem_in_order() {
        let mut p = Problems::default();
        assert_eq!(p.within_open("a.rate_hz", 0.0, 0.0, 10.0), None);
        assert_eq!(p.within_closed("a.std_m", 0.0, 0.0, 10.0), Some(0.0));
        assert_eq!(p.within_closed("b.std_m", f64::NAN, 0.0, 10.0), None);
        assert_eq!(p.check(false, "c.count", "must be > 0", 0u32), None);
        let list = p.into_vec();
        let keys: Vec<&str> = list.iter().map(|p| p.key.as_str()).collect();
        assert_eq!(keys, ["a.rate_hz", "b.std_m", "c.count"]);
        assert_eq!(
            list[0].to_string(),
            "`a.rate_hz`: must be a number in (0, 10], got 0"
        );
    }

    #[test]
    fn periods_and_durations_that_do_not_exist_are_problems() {
        let mut p = Problems::default();
        assert_eq!(
            period(&mut p, "x.hz", 2.0),
            Some(Duration::from_millis(500))
        );
        assert_eq!(
            millis(&mut p, "x.ms", 1500.0),
            Some(Duration::from_millis(1500))
        );
        assert!(p.is_empty());
        assert_eq!(period(&mut p, "y.hz", 1e-320), None);
        assert_eq!(millis(&mut p, "y.ms", -1.0), None);
        let keys: Vec<String> = p.into_vec().into_iter().map(|p| p.key).collect();
        assert_eq!(keys, ["y.hz", "y.ms"]);
    }

    #[test]
    fn an_empty_refusal_still_names_a_problem() {
        assert_eq!(Problems::default().into_vec().len(), 1);
    }
}
