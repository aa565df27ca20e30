//! Losing a camera and getting it back, as a pure state machine: the capture loop feeds it
//! what happened (open failed, read failed, a frame arrived) and it answers what to tell the
//! operator and how long to wait before the next attempt. No clock and no sleeping here, so
//! the schedule is tested without waiting.

use std::time::Duration;

/// Reconnect delays: `initial`, doubling after every failure up to `max`, back to `initial`
/// once frames flow again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Backoff {
    /// First delay after a loss.
    initial: Duration,
    /// Cap of the doubling.
    max: Duration,
    /// The delay the next failure gets.
    next: Duration,
}

impl Backoff {
    /// A schedule from `initial` doubling to `max` (`max` below `initial` is raised to it).
    pub fn new(initial: Duration, max: Duration) -> Self {
        Self {
            initial,
            max: max.max(initial),
            next: initial,
        }
    }

    /// The delay before the next attempt; doubles the one after it.
    pub fn next_delay(&mut self) -> Duration {
        let d = self.next;
        self.next = self.next.saturating_mul(2).min(self.max);
        d
    }

    /// Back to the initial delay.
    pub fn reset(&mut self) {
        self.next = self.initial;
    }
}

/// A change the operator is told about (STATUSTEXT).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraStatus {
    /// No frames: the source could not be opened or stopped working.
    Lost,
    /// Frames flow again after a loss.
    Back,
    /// The source is there but refuses mgmot (permission denied): said once per episode,
    /// after [`CameraStatus::Lost`], so that a socket or device node that appears with the
    /// wrong permissions is not retried in silence.
    Denied,
}

/// Whether the camera is lost, and the backoff of the attempts to get it back.
#[derive(Debug, Clone)]
pub struct Reconnect {
    /// The delay schedule.
    backoff: Backoff,
    /// "Lost" has been reported and "back" not yet: each is said once per loss.
    lost: bool,
    /// "Denied" has been reported and the source has not opened or gone missing since.
    denied: bool,
}

impl Reconnect {
    /// Starts in the "not lost" state.
    pub fn new(backoff: Backoff) -> Self {
        Self {
            backoff,
            lost: false,
            denied: false,
        }
    }

    /// An open failed; `denied`: for lack of permission. True when that is news to report
    /// ([`CameraStatus::Denied`]): the first denial of an episode, which ends when the source
    /// opens or fails for another reason.
    pub fn refused(&mut self, denied: bool) -> bool {
        if denied {
            !std::mem::replace(&mut self.denied, true)
        } else {
            self.denied = false;
            false
        }
    }

    /// Opening the source failed: report "lost" if not yet reported, wait the returned delay.
    pub fn open_failed(&mut self) -> (Option<CameraStatus>, Duration) {
        (self.mark_lost(), self.backoff.next_delay())
    }

    /// The open source failed while reading: as [`Reconnect::open_failed`] (a source that
    /// opens and fails at once is retried on the same growing schedule, not in a tight loop).
    pub fn read_failed(&mut self) -> (Option<CameraStatus>, Duration) {
        self.open_failed()
    }

    /// A frame arrived: report "back" if a loss was reported, and reset the backoff.
    pub fn frame(&mut self) -> Option<CameraStatus> {
        self.backoff.reset();
        if std::mem::take(&mut self.lost) {
            Some(CameraStatus::Back)
        } else {
            None
        }
    }

    /// True between a reported loss and the first frame after it.
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    fn mark_lost(&mut self) -> Option<CameraStatus> {
        if self.lost {
            None
        } else {
            self.lost = true;
            Some(CameraStatus::Lost)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: Duration = Duration::from_secs(1);

    #[test]
    fn backoff_doubles_to_the_cap_and_resets() {
        let mut b = Backoff::new(S, 5 * S);
        let d: Vec<_> = (0..5).map(|_| b.next_delay()).collect();
        assert_eq!(d, [S, 2 * S, 4 * S, 5 * S, 5 * S]);
        b.reset();
        assert_eq!(b.next_delay(), S);
        let mut odd = Backoff::new(3 * S, S);
        assert_eq!((odd.next_delay(), odd.next_delay()), (3 * S, 3 * S));
    }

    /// A device that is missing at start, comes, streams, is unplugged for a while, comes back.
    #[test]
    fn lost_and_back_are_said_once_per_loss() {
        let mut r = Reconnect::new(Backoff::new(S, 5 * S));
        assert_eq!(r.open_failed(), (Some(CameraStatus::Lost), S));
        assert_eq!(r.open_failed(), (None, 2 * S));
        assert!(r.is_lost());
        // Opened: nothing is said until a frame arrives.
        assert_eq!(r.frame(), Some(CameraStatus::Back));
        assert_eq!(r.frame(), None);
        assert!(!r.is_lost());
        // Unplugged: read fails, then the node is gone for three attempts.
        assert_eq!(r.read_failed(), (Some(CameraStatus::Lost), S));
        assert_eq!(r.open_failed(), (None, 2 * S));
        assert_eq!(r.open_failed(), (None, 4 * S));
        assert_eq!(r.open_failed(), (None, 5 * S));
        // Replugged, opens, but the first read fails: still lost, still backing off.
        assert_eq!(r.read_failed(), (None, 5 * S));
        assert_eq!(r.frame(), Some(CameraStatus::Back));
        // The next loss starts the schedule again.
        assert_eq!(r.read_failed(), (Some(CameraStatus::Lost), S));
    }
}
