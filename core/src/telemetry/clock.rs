//! Mapping the autopilot's clock onto the companion's monotonic clock.
//!
//! Two estimates of `offset = companion - autopilot`:
//!
//! - **TIMESYNC** (preferred): the companion sends its time `ts1`, the autopilot answers with its
//!   own time `tc1`; if the answer arrives at `t_rx`, the autopilot read its clock about halfway,
//!   so `offset = (ts1 + t_rx) / 2 - tc1`, wrong by at most half the round trip. The estimate
//!   with the shortest round trip among the last [`TIMESYNC_WINDOW`] exchanges is used.
//! - **Arrival time** (fallback, no TIMESYNC answers): every stamped message arrives some
//!   non-negative transport delay after its stamp, so `arrival - stamp >= offset`; the minimum
//!   over the last [`ARRIVAL_WINDOW`] messages approaches the offset from above by the smallest
//!   delay seen.
//!
//! An autopilot reboot resets both. What is a reboot is decided in one place,
//! [`RebootDetector`], which the link (stream requests) and the pose buffer follow too: the
//! clock jumps back by more than [`REBOOT_JUMP_US`], and the new timeline then holds alone, for
//! [`REBOOT_CONFIRM`] stamps in a row covering at least [`REBOOT_CONFIRM_SPAN_US`] of it, with
//! no stamp of the old timeline in between, or at once after the old timeline had been silent
//! for [`REBOOT_AFTER_SILENCE_US`]. A lone old stamp (a delayed or replayed packet, a
//! stray or forged message stamped near zero) is ignored instead, and the reset is logged at
//! most every [`LOG_EVERY_US`], so old stamps can neither wipe the mapping packet by packet
//! nor flood the log.

use super::{AutopilotTimeUs, CompanionTimeUs};
use std::collections::VecDeque;

/// TIMESYNC exchanges kept: at the usual 1 Hz, the last 16 s; enough to find one exchange that
/// was not delayed by a busy link, short enough to follow clock drift (tens of ppm).
pub const TIMESYNC_WINDOW: usize = 16;

/// Stamped messages kept for the arrival-time estimate: at a few hundred messages per second,
/// a few seconds of history.
pub const ARRIVAL_WINDOW: usize = 1024;

/// A jump back of the autopilot clock by more than this is a reboot, not reordering.
pub const REBOOT_JUMP_US: u64 = 2_000_000;

/// Stamps in a row behind the latest by more than [`REBOOT_JUMP_US`] that make a reboot.
pub const REBOOT_CONFIRM: u32 = 3;

/// How much of the new timeline those stamps must cover (autopilot µs): a rebooted autopilot
/// streams at tens of hertz within a second, while a stray or forged message now and then
/// between the real ones never holds the new timeline alone this long.
pub const REBOOT_CONFIRM_SPAN_US: u64 = 500_000;

/// After the current timeline has been silent this long (companion µs), the first stamp far
/// behind it is a reboot at once: a rebooting autopilot is silent for seconds, and a forger
/// cannot silence the real one.
pub const REBOOT_AFTER_SILENCE_US: u64 = 1_000_000;

/// The reboot warning is logged at most this often (companion µs); the others are counted.
pub const LOG_EVERY_US: u64 = 10_000_000;

/// Which estimate the mapping currently uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockSource {
    /// No estimate yet.
    Unknown,
    /// Minimum arrival delay of stamped messages.
    Arrival,
    /// TIMESYNC round trips.
    TimeSync,
}

/// One TIMESYNC exchange.
#[derive(Debug, Clone, Copy)]
struct Exchange {
    offset_us: i64,
    round_trip_us: u64,
}

/// What a new autopilot stamp means, as [`RebootDetector::observe`] judges it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StampVerdict {
    /// On the current timeline (or reordered by less than [`REBOOT_JUMP_US`]): use it.
    Current,
    /// Far behind the latest without (yet) making a reboot (a delayed, replayed, stray or
    /// forged stamp), or further ahead of the latest than the companion's clock moved since
    /// it arrived (a stamp from the future). Do not use it.
    Stale,
    /// This stamp confirmed a reboot: everything kept on the old timeline is void; the stamp
    /// itself is the first to use on the new one.
    Rebooted {
        /// The latest stamp of the old timeline.
        from: AutopilotTimeUs,
    },
}

/// Decides, stamp by stamp, whether the autopilot rebooted (see the module doc): the one
/// judge the clock mapping, the pose buffer and the link's stream requests follow.
#[derive(Debug, Clone, Default)]
pub struct RebootDetector {
    /// Latest autopilot stamp seen on the current timeline, and when it arrived.
    latest: Option<(AutopilotTimeUs, CompanionTimeUs)>,
    /// Stamps in a row far behind `latest`: the first and newest of them, and how many.
    behind: Option<(AutopilotTimeUs, AutopilotTimeUs, u32)>,
    /// Stamps ignored as far behind without making a reboot.
    stale_stamps: u64,
    /// Reboots confirmed.
    reboots: u64,
}

impl RebootDetector {
    /// Nothing seen yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Judges the autopilot stamp `t` that arrived at companion time `at`.
    pub fn observe(&mut self, t: AutopilotTimeUs, at: CompanionTimeUs) -> StampVerdict {
        let Some((latest, latest_at)) = self.latest else {
            self.latest = Some((t, at));
            return StampVerdict::Current;
        };
        let moved_us = at.0.saturating_sub(latest_at.0);
        if t.0
            > latest
                .0
                .saturating_add(moved_us)
                .saturating_add(REBOOT_JUMP_US)
        {
            // Ahead of the latest by more than the time that passed since it arrived.
            self.stale_stamps += 1;
            return StampVerdict::Stale;
        }
        if latest.0 <= t.0.saturating_add(REBOOT_JUMP_US) {
            // On the current timeline (or reordered by less than the jump): any run of far
            // older stamps is broken by it.
            self.behind = None;
            if t >= latest {
                self.latest = Some((t, at));
            }
            return StampVerdict::Current;
        }
        // Far behind: after a silence of the current timeline, a reboot at once.
        if moved_us >= REBOOT_AFTER_SILENCE_US {
            self.behind = None;
            self.reboots += 1;
            self.latest = Some((t, at));
            return StampVerdict::Rebooted { from: latest };
        }
        // Otherwise only if the stamps hold one new timeline alone, long enough.
        let (first, count) = match self.behind {
            Some((first, prev, n))
                if t.0 >= prev.0 && t.0 <= prev.0.saturating_add(REBOOT_JUMP_US) =>
            {
                (first, n + 1)
            }
            _ => (t, 1),
        };
        if count < REBOOT_CONFIRM || t.0.saturating_sub(first.0) < REBOOT_CONFIRM_SPAN_US {
            self.behind = Some((first, t, count));
            self.stale_stamps += 1;
            return StampVerdict::Stale;
        }
        self.behind = None;
        self.reboots += 1;
        self.latest = Some((t, at));
        StampVerdict::Rebooted { from: latest }
    }

    /// Stamps ignored as far behind the latest without making a reboot.
    pub fn stale_stamps(&self) -> u64 {
        self.stale_stamps
    }

    /// Reboots confirmed since start.
    pub fn reboots(&self) -> u64 {
        self.reboots
    }
}

/// The clock mapping between autopilot and companion.
#[derive(Debug, Clone, Default)]
pub struct ClockSync {
    /// Recent TIMESYNC exchanges; the shortest round trip wins.
    exchanges: VecDeque<Exchange>,
    /// Recent `arrival - stamp` values (µs), for the fallback.
    arrivals: VecDeque<i64>,
    /// Whether a stamp is current, stale or a reboot.
    reboots: RebootDetector,
    /// When the reset warning was last logged (companion µs), and resets not logged since.
    last_warning: Option<(u64, u64)>,
}

impl ClockSync {
    /// An empty mapping.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records a TIMESYNC answer: `sent` is our `ts1` (companion time we put in the request),
    /// `autopilot` its `tc1`, `received` when the answer arrived. Returns the round trip (µs),
    /// or `None` when the answer is inconsistent (arrived before it was sent).
    pub fn observe_timesync(
        &mut self,
        sent: CompanionTimeUs,
        autopilot: AutopilotTimeUs,
        received: CompanionTimeUs,
    ) -> Option<u64> {
        let round_trip_us = received.0.checked_sub(sent.0)?;
        if self.note_autopilot_time(autopilot, received) == StampVerdict::Stale {
            return None;
        }
        let midpoint = sent.0 as i128 + i128::from(round_trip_us / 2);
        let offset_us = i64::try_from(midpoint - autopilot.0 as i128).ok()?;
        if self.exchanges.len() == TIMESYNC_WINDOW {
            self.exchanges.pop_front();
        }
        self.exchanges.push_back(Exchange {
            offset_us,
            round_trip_us,
        });
        Some(round_trip_us)
    }

    /// Records a message stamped `stamp` by the autopilot that arrived at `arrival`, and
    /// says what the stamp means: a [`StampVerdict::Stale`] message's contents must not be
    /// used either, and after [`StampVerdict::Rebooted`] whatever was kept on the old
    /// timeline (the pose history) is void.
    pub fn observe_arrival(
        &mut self,
        stamp: AutopilotTimeUs,
        arrival: CompanionTimeUs,
    ) -> StampVerdict {
        let verdict = self.note_autopilot_time(stamp, arrival);
        if verdict == StampVerdict::Stale {
            return verdict;
        }
        let Ok(delta) = i64::try_from(arrival.0 as i128 - stamp.0 as i128) else {
            return verdict;
        };
        if self.arrivals.len() == ARRIVAL_WINDOW {
            self.arrivals.pop_front();
        }
        self.arrivals.push_back(delta);
        verdict
    }

    /// Notes the autopilot stamp `t` seen at companion time `now` and returns the verdict; a
    /// reboot resets the mapping.
    fn note_autopilot_time(&mut self, t: AutopilotTimeUs, now: CompanionTimeUs) -> StampVerdict {
        let verdict = self.reboots.observe(t, now);
        let StampVerdict::Rebooted { from } = verdict else {
            return verdict;
        };
        self.exchanges.clear();
        self.arrivals.clear();
        let due = self
            .last_warning
            .is_none_or(|(at, _)| now.0.saturating_sub(at) >= LOG_EVERY_US);
        if due {
            let suppressed = self.last_warning.map_or(0, |(_, n)| n);
            tracing::warn!(
                from_us = from.0,
                to_us = t.0,
                resets = self.reboots.reboots(),
                suppressed,
                "autopilot clock jumped back: reboot; clock mapping reset"
            );
            self.last_warning = Some((now.0, 0));
        } else if let Some((_, n)) = self.last_warning.as_mut() {
            *n += 1;
        }
        verdict
    }

    /// Stamps ignored as far behind the latest without making a reboot (delayed, replayed).
    pub fn stale_stamps(&self) -> u64 {
        self.reboots.stale_stamps()
    }

    /// Times the mapping was reset for an autopilot reboot.
    pub fn resets(&self) -> u64 {
        self.reboots.reboots()
    }

    /// The estimate in use.
    pub fn source(&self) -> ClockSource {
        if !self.exchanges.is_empty() {
            ClockSource::TimeSync
        } else if !self.arrivals.is_empty() {
            ClockSource::Arrival
        } else {
            ClockSource::Unknown
        }
    }

    /// `companion - autopilot` (µs), if known.
    pub fn offset_us(&self) -> Option<i64> {
        if let Some(best) = self.exchanges.iter().min_by_key(|e| e.round_trip_us) {
            return Some(best.offset_us);
        }
        self.arrivals.iter().copied().min()
    }

    /// The companion time of an autopilot time.
    pub fn to_companion(&self, t: AutopilotTimeUs) -> Option<CompanionTimeUs> {
        let v = t.0 as i128 + i128::from(self.offset_us()?);
        u64::try_from(v).ok().map(CompanionTimeUs)
    }

    /// The autopilot time of a companion time (`None` before the autopilot booted or when no
    /// estimate exists).
    pub fn to_autopilot(&self, t: CompanionTimeUs) -> Option<AutopilotTimeUs> {
        let v = t.0 as i128 - i128::from(self.offset_us()?);
        u64::try_from(v).ok().map(AutopilotTimeUs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn unknown_until_observed() {
        let c = ClockSync::new();
        assert_eq!(c.source(), ClockSource::Unknown);
        assert_eq!(c.to_autopilot(CompanionTimeUs(5)), None);
    }

    #[test]
    fn timesync_beats_arrival_and_shortest_round_trip_wins() {
        let mut c = ClockSync::new();
        // True offset: companion = autopilot + 1_000_000.
        c.observe_arrival(AutopilotTimeUs(10_000), CompanionTimeUs(1_015_000));
        assert_eq!(c.source(), ClockSource::Arrival);
        assert_eq!(c.offset_us(), Some(1_005_000));
        // A slow exchange (asymmetric: 30 ms out, 10 ms back) and a fast symmetric one.
        c.observe_timesync(
            CompanionTimeUs(1_100_000),
            AutopilotTimeUs(130_000),
            CompanionTimeUs(1_140_000),
        );
        c.observe_timesync(
            CompanionTimeUs(1_200_000),
            AutopilotTimeUs(201_000),
            CompanionTimeUs(1_202_000),
        );
        assert_eq!(c.source(), ClockSource::TimeSync);
        assert_eq!(c.offset_us(), Some(1_000_000));
        assert_eq!(
            c.to_autopilot(CompanionTimeUs(1_500_000)),
            Some(AutopilotTimeUs(500_000))
        );
        assert_eq!(
            c.to_companion(AutopilotTimeUs(500_000)),
            Some(CompanionTimeUs(1_500_000))
        );
    }

    #[test]
    fn answer_before_request_is_rejected() {
        let mut c = ClockSync::new();
        assert_eq!(
            c.observe_timesync(CompanionTimeUs(10), AutopilotTimeUs(5), CompanionTimeUs(9)),
            None
        );
        assert_eq!(c.source(), ClockSource::Unknown);
    }

    #[test]
    fn reboot_resets() {
        let mut c = ClockSync::new();
        // The old timeline streams until the new one starts (no silence between).
        c.observe_arrival(AutopilotTimeUs(100_000_000), CompanionTimeUs(100_500_000));
        c.observe_arrival(AutopilotTimeUs(199_500_000), CompanionTimeUs(200_000_000));
        // The new timeline at 50 Hz: the reboot is confirmed once it held alone for
        // REBOOT_CONFIRM_SPAN_US, not before.
        let mut k = 0u64;
        loop {
            let verdict = c.observe_arrival(
                AutopilotTimeUs(1_000 + k * 20_000),
                CompanionTimeUs(200_001_000 + k * 20_000),
            );
            if k * 20_000 < REBOOT_CONFIRM_SPAN_US {
                assert_eq!(verdict, StampVerdict::Stale, "stamp {k}");
                assert_eq!(c.offset_us(), Some(500_000), "reset after {k} stamps");
            } else {
                assert_eq!(
                    verdict,
                    StampVerdict::Rebooted {
                        from: AutopilotTimeUs(199_500_000)
                    }
                );
                break;
            }
            k += 1;
        }
        assert_eq!(c.offset_us(), Some(200_000_000));
        assert_eq!(c.resets(), 1);
    }

    /// A rebooting autopilot is silent for seconds: the first stamp of the new boot after that
    /// silence is a reboot at once.
    #[test]
    fn after_a_silence_the_first_stamp_far_behind_is_a_reboot() {
        let mut d = RebootDetector::new();
        assert_eq!(
            d.observe(AutopilotTimeUs(30_000_000), CompanionTimeUs(50_000_000)),
            StampVerdict::Current
        );
        assert_eq!(
            d.observe(
                AutopilotTimeUs(1_000),
                CompanionTimeUs(50_000_000 + REBOOT_AFTER_SILENCE_US)
            ),
            StampVerdict::Rebooted {
                from: AutopilotTimeUs(30_000_000)
            }
        );
    }

    /// A stray or forged message stamped near zero every 100 ms among the autopilot's 50 Hz
    /// stream, even in bursts of several in a row, is never a reboot.
    #[test]
    fn forged_stamps_near_zero_are_never_a_reboot() {
        let mut d = RebootDetector::new();
        let mut forged = 0u64;
        for k in 0..5_000u64 {
            let at = CompanionTimeUs(900_000_000 + k * 20_000);
            let real = AutopilotTimeUs(300_000_000 + k * 20_000);
            assert_eq!(d.observe(real, at), StampVerdict::Current);
            if k % 5 == 0 {
                // Five forged stamps in a row, 100 ms apart on their own timeline.
                for _ in 0..5 {
                    let stamp = AutopilotTimeUs((forged % 100) * 100_000);
                    assert_eq!(d.observe(stamp, at), StampVerdict::Stale);
                    forged += 1;
                }
            }
        }
        // One stamp from the future is not used either, nor does it move the timeline.
        let at = CompanionTimeUs(900_000_000 + 5_000 * 20_000);
        assert_eq!(
            d.observe(AutopilotTimeUs(4_000_000_000), at),
            StampVerdict::Stale
        );
        assert_eq!(
            d.observe(AutopilotTimeUs(300_000_000 + 5_000 * 20_000), at),
            StampVerdict::Current
        );
        assert_eq!(d.reboots(), 0);
        assert_eq!(d.stale_stamps(), 5_001);
    }

    /// Old stamps between current ones (a delayed or replayed packet, a spoofer) neither
    /// reset the mapping nor are used.
    #[test]
    fn lone_old_stamps_are_ignored() {
        let mut c = ClockSync::new();
        for k in 0..1000u64 {
            let now = 100_000_000 + k * 10_000;
            c.observe_arrival(AutopilotTimeUs(now - 500_000), CompanionTimeUs(now));
            if k % 2 == 0 {
                c.observe_arrival(AutopilotTimeUs(1_000 + k), CompanionTimeUs(now));
            }
        }
        assert_eq!(c.offset_us(), Some(500_000));
        assert_eq!(c.resets(), 0);
        assert_eq!(c.stale_stamps(), 500);
    }

    proptest! {
        /// With random non-negative delays the arrival estimate is never below the true offset
        /// and is above it by exactly the smallest delay.
        #[test]
        fn arrival_estimate_bounds(offset in 0i64..1_000_000_000, delays in proptest::collection::vec(0u64..50_000, 1..200)) {
            let mut c = ClockSync::new();
            for (k, d) in delays.iter().enumerate() {
                let stamp = 1_000_000 + 20_000 * k as u64;
                c.observe_arrival(AutopilotTimeUs(stamp), CompanionTimeUs((stamp as i64 + offset) as u64 + d));
            }
            let min_delay = *delays.iter().min().unwrap() as i64;
            prop_assert_eq!(c.offset_us(), Some(offset + min_delay));
        }

        /// A TIMESYNC estimate is off by at most half the round trip of the best exchange.
        #[test]
        fn timesync_error_within_half_round_trip(offset in 0i64..1_000_000_000, legs in proptest::collection::vec((0u64..20_000, 0u64..20_000), 1..=TIMESYNC_WINDOW)) {
            let mut c = ClockSync::new();
            let mut best_rtt = u64::MAX;
            for (k, (up, down)) in legs.iter().enumerate() {
                let sent = 2_000_000_000 + 1_000_000 * k as u64;
                let autopilot = (sent as i64 - offset + *up as i64).max(0) as u64;
                let received = (autopilot as i64 + offset) as u64 + down;
                if let Some(rtt) = c.observe_timesync(CompanionTimeUs(sent), AutopilotTimeUs(autopilot), CompanionTimeUs(received)) {
                    best_rtt = best_rtt.min(rtt);
                }
            }
            if let Some(est) = c.offset_us() {
                prop_assert!((est - offset).unsigned_abs() <= best_rtt / 2 + 1);
            }
        }
    }
}
