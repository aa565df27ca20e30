//! TIMESYNC requests mgmot has sent and is waiting on. An answer counts only when it carries
//! the `ts1` of one of them (and the link checks it came from the autopilot): a ground station
//! answering the requests the autopilot forwards, or anyone else, cannot move the clock
//! mapping, and each request is answered at most once. Pure: times are passed in.

use std::collections::VecDeque;

/// Requests remembered: at 1 Hz, the last 16 s.
const OUTSTANDING: usize = 16;

/// An answer older than this (µs) is not used: its round trip says nothing useful.
const MAX_ROUND_TRIP_US: u64 = 10_000_000;

/// The requests waiting for an answer.
#[derive(Debug, Default, Clone)]
pub struct TimeSyncRequests {
    /// `ts1` in ns (our companion time) of each request still unanswered.
    outstanding: VecDeque<i64>,
}

impl TimeSyncRequests {
    /// None yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// A request with `ts1_ns` was sent.
    pub fn sent(&mut self, ts1_ns: i64) {
        if self.outstanding.len() == OUTSTANDING {
            self.outstanding.pop_front();
        }
        self.outstanding.push_back(ts1_ns);
    }

    /// An answer echoing `ts1_ns` arrived at companion time `now_us`: whether it answers one
    /// of our requests (which is then no longer outstanding).
    pub fn answer(&mut self, ts1_ns: i64, now_us: u64) -> bool {
        let Some(i) = self.outstanding.iter().position(|&t| t == ts1_ns) else {
            return false;
        };
        self.outstanding.remove(i);
        let sent_us = u64::try_from(ts1_ns / 1000).unwrap_or(u64::MAX);
        now_us >= sent_us && now_us - sent_us <= MAX_ROUND_TRIP_US
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_our_requests_are_answered_and_only_once() {
        let mut t = TimeSyncRequests::new();
        t.sent(5_000_000);
        assert!(!t.answer(4_000_000, 6_000), "not a request of ours");
        assert!(t.answer(5_000_000, 6_000));
        assert!(!t.answer(5_000_000, 6_000), "answered twice");
    }

    #[test]
    fn stale_and_future_answers_are_refused() {
        let mut t = TimeSyncRequests::new();
        t.sent(1_000_000_000);
        assert!(!t.answer(1_000_000_000, 999_000), "before it was sent");
        t.sent(1_000_000_000);
        assert!(!t.answer(1_000_000_000, 12_000_000), "11 s round trip");
    }

    #[test]
    fn only_the_last_requests_are_remembered() {
        let mut t = TimeSyncRequests::new();
        for i in 0..100 {
            t.sent(i * 1000);
        }
        assert!(!t.answer(0, 100));
        assert!(t.answer(99_000, 100));
    }
}
