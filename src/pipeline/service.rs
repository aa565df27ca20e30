//! systemd service notifications (`sd_notify(3)`) for `mgmot run` as a `Type=notify` service
//! (`systemd/mgmot.service`), sent from the frame-step thread:
//!
//! - `READY=1` once, when both flow: a frame was processed within [`FRAMES_FLOW_WITHIN`] and a
//!   position fix arrived within `telemetry.lost_after_ms`. Not at start-up: a service that
//!   never sees the autopilot or the camera never becomes ready.
//! - Before that, `EXTEND_TIMEOUT_USEC=` while the frame loop runs, so that waiting for the
//!   autopilot or the camera is not a start-up failure, but a frame loop that hangs is
//!   (systemd's `TimeoutStartSec=` then stops it).
//! - After it, `WATCHDOG=1` every half `WATCHDOG_USEC` (systemd's `WatchdogSec=`), only while
//!   frames are processed: a ping is sent only if a frame was processed since the previous
//!   one. A stalled pipeline (no frame from the camera, a detector that hangs) stops the pings
//!   and systemd restarts the service between one and one and a half `WatchdogSec=` after the
//!   last frame.
//! - `STATUS=` (what `systemctl status mgmot` shows) every [`STATUS_EVERY`]: what start-up
//!   waits for, then the tracks and the frame rate, or how long frames have been missing.
//! - `STOPPING=1` when the frame step ends (shutdown, or the source's end).
//!
//! Every call is a no-op when `NOTIFY_SOCKET` is unset (mgmot not started by systemd). The
//! decisions ([`Plan`]) are kept apart from the sending, and take the time as an argument.

use super::telemetry::TelemetryState;
use sd_notify::NotifyState;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Frames "flow" when one was processed within this long.
pub(super) const FRAMES_FLOW_WITHIN: Duration = Duration::from_secs(2);

/// How often the `STATUS=` line is refreshed (it carries the frame rate).
pub(super) const STATUS_EVERY: Duration = Duration::from_secs(2);

/// The start-up extension when systemd gives no watchdog interval (`EXTEND_TIMEOUT_USEC=`);
/// with one, the extension is the watchdog interval.
const EXTEND_WITHOUT_WATCHDOG: Duration = Duration::from_secs(30);

/// One notification.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Message {
    /// `READY=1`.
    Ready,
    /// `WATCHDOG=1`.
    Watchdog,
    /// `EXTEND_TIMEOUT_USEC=`: start-up may take this much longer.
    ExtendTimeout(Duration),
    /// `STATUS=`.
    Status(String),
    /// `STOPPING=1`.
    Stopping,
}

/// What the frame step has seen at one tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Seen {
    /// A position fix arrived within `telemetry.lost_after_ms`.
    pub telemetry_fresh: bool,
}

/// The notification decisions, without the sending.
#[derive(Debug)]
pub(super) struct Plan {
    /// Half the watchdog interval; `None`: no watchdog asked for.
    ping_every: Option<Duration>,
    /// `EXTEND_TIMEOUT_USEC=` value before READY, sent every third of it.
    extend_by: Duration,
    ready: bool,
    frames: u64,
    tracks: usize,
    last_frame_at: Option<Instant>,
    last_ping: Option<(Instant, u64)>,
    last_extend: Option<Instant>,
    last_status: Option<(Instant, u64)>,
}

impl Plan {
    /// A plan for a watchdog interval `watchdog` (`WATCHDOG_USEC`), if any.
    pub fn new(watchdog: Option<Duration>) -> Self {
        Self {
            ping_every: watchdog.map(|w| w / 2).filter(|p| !p.is_zero()),
            extend_by: watchdog.unwrap_or(EXTEND_WITHOUT_WATCHDOG),
            ready: false,
            frames: 0,
            tracks: 0,
            last_frame_at: None,
            last_ping: None,
            last_extend: None,
            last_status: None,
        }
    }

    /// A frame went through the detector and the tracker at `now`, with `tracks` confirmed
    /// tracks in the output.
    pub fn frame_processed(&mut self, now: Instant, tracks: usize) {
        self.frames += 1;
        self.tracks = tracks;
        self.last_frame_at = Some(now);
    }

    /// What is due at `now`.
    pub fn tick(&mut self, now: Instant, seen: Seen) -> Vec<Message> {
        let mut out = Vec::new();
        let frames_flow = self
            .last_frame_at
            .is_some_and(|at| now.saturating_duration_since(at) <= FRAMES_FLOW_WITHIN);
        let mut status_now = false;
        if !self.ready && frames_flow && seen.telemetry_fresh {
            self.ready = true;
            status_now = true;
            out.push(Message::Ready);
            self.last_ping = Some((now, self.frames));
        } else if !self.ready
            && self
                .last_extend
                .is_none_or(|at| now.saturating_duration_since(at) >= self.extend_by / 3)
        {
            self.last_extend = Some(now);
            out.push(Message::ExtendTimeout(self.extend_by));
        }
        if let (true, Some(every), Some((at, frames))) =
            (self.ready, self.ping_every, self.last_ping)
        {
            if now.saturating_duration_since(at) >= every && self.frames > frames {
                self.last_ping = Some((now, self.frames));
                out.push(Message::Watchdog);
            }
        }
        let due = self
            .last_status
            .is_none_or(|(at, _)| now.saturating_duration_since(at) >= STATUS_EVERY);
        if status_now || due {
            out.push(Message::Status(self.status(now, frames_flow, seen)));
            self.last_status = Some((now, self.frames));
        }
        out
    }

    /// The `STATUS=` text.
    fn status(&self, now: Instant, frames_flow: bool, seen: Seen) -> String {
        if !self.ready {
            return match (seen.telemetry_fresh, frames_flow) {
                (false, false) => "waiting for telemetry and frames".to_owned(),
                (false, true) => "waiting for telemetry (frames flow)".to_owned(),
                _ => "waiting for frames (telemetry flows)".to_owned(),
            };
        }
        if !frames_flow {
            let since = self
                .last_frame_at
                .map_or(0.0, |at| now.saturating_duration_since(at).as_secs_f64());
            return format!("no frames for {since:.0} s");
        }
        let fps = match self.last_status {
            Some((at, frames)) if now > at => {
                (self.frames - frames) as f64 / (now - at).as_secs_f64()
            }
            _ => 0.0,
        };
        let telemetry = if seen.telemetry_fresh {
            ""
        } else {
            ", telemetry lost (tracking in the image only)"
        };
        format!("tracking: {} tracks, {fps:.0} fps{telemetry}", self.tracks)
    }
}

/// Sends [`Plan`]'s notifications to systemd; a no-op without `NOTIFY_SOCKET`.
#[derive(Debug)]
pub(super) struct ServiceNotifier {
    /// `None`: not started by systemd with `Type=notify`.
    plan: Option<Plan>,
    /// `telemetry.lost_after_ms`.
    lost_after_us: u64,
    /// A failed send is logged as a warning once, then at debug level.
    send_failed: bool,
}

impl ServiceNotifier {
    /// From the environment systemd sets (`NOTIFY_SOCKET`, `WATCHDOG_USEC`, `WATCHDOG_PID`);
    /// telemetry is fresh when a position fix arrived within `lost_after`.
    pub fn from_env(lost_after: Duration) -> Self {
        let plan = std::env::var_os("NOTIFY_SOCKET").map(|_| {
            let watchdog = sd_notify::watchdog_enabled();
            tracing::info!(?watchdog, "systemd notifications on");
            Plan::new(watchdog)
        });
        Self {
            plan,
            lost_after_us: u64::try_from(lost_after.as_micros()).unwrap_or(u64::MAX),
            send_failed: false,
        }
    }

    /// A frame went through the detector and the tracker, with `tracks` confirmed tracks.
    pub fn frame_processed(&mut self, tracks: usize) {
        if let Some(plan) = &mut self.plan {
            plan.frame_processed(Instant::now(), tracks);
        }
    }

    /// Sends what is due; called once per turn of the frame loop.
    pub fn tick(&mut self, telemetry: &Mutex<TelemetryState>) {
        let Some(plan) = &mut self.plan else { return };
        let now = crate::clock::now();
        let telemetry_fresh = telemetry
            .lock()
            .ok()
            .and_then(|t| t.last_position_at())
            .is_some_and(|at| now.0.saturating_sub(at.0) <= self.lost_after_us);
        let due = plan.tick(Instant::now(), Seen { telemetry_fresh });
        if due.contains(&Message::Ready) {
            tracing::info!("telemetry and frames flow: ready (systemd READY=1)");
        }
        self.send(&due);
    }

    /// `STOPPING=1`: the frame step has ended.
    pub fn stopping(&mut self) {
        if self.plan.is_some() {
            self.send(&[Message::Stopping, Message::Status("stopping".to_owned())]);
        }
    }

    fn send(&mut self, messages: &[Message]) {
        if messages.is_empty() {
            return;
        }
        let states: Vec<NotifyState<'_>> = messages
            .iter()
            .map(|m| match m {
                Message::Ready => NotifyState::Ready,
                Message::Watchdog => NotifyState::Watchdog,
                Message::ExtendTimeout(d) => {
                    NotifyState::ExtendTimeoutUsec(u32::try_from(d.as_micros()).unwrap_or(u32::MAX))
                }
                Message::Status(s) => NotifyState::Status(s),
                Message::Stopping => NotifyState::Stopping,
            })
            .collect();
        if let Err(e) = sd_notify::notify(&states) {
            if self.send_failed {
                tracing::debug!(error = %e, "systemd notification not sent");
            } else {
                tracing::warn!(error = %e, "systemd notification not sent (NOTIFY_SOCKET)");
                self.send_failed = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FRESH: Seen = Seen {
        telemetry_fresh: true,
    };
    const STALE: Seen = Seen {
        telemetry_fresh: false,
    };

    fn has(m: &[Message], what: &Message) -> bool {
        m.contains(what)
    }

    fn status(m: &[Message]) -> Option<&str> {
        m.iter().find_map(|m| match m {
            Message::Status(s) => Some(s.as_str()),
            _ => None,
        })
    }

    #[test]
    fn ready_needs_both_frames_and_telemetry() {
        let t0 = Instant::now();
        let mut p = Plan::new(Some(Duration::from_secs(10)));
        let first = p.tick(t0, STALE);
        assert!(!has(&first, &Message::Ready));
        assert!(has(
            &first,
            &Message::ExtendTimeout(Duration::from_secs(10))
        ));
        assert_eq!(status(&first), Some("waiting for telemetry and frames"));
        // Telemetry alone.
        let m = p.tick(t0 + Duration::from_secs(3), FRESH);
        assert!(!has(&m, &Message::Ready));
        assert_eq!(status(&m), Some("waiting for frames (telemetry flows)"));
        // Frames alone.
        p.frame_processed(t0 + Duration::from_secs(5), 0);
        let m = p.tick(t0 + Duration::from_secs(5), STALE);
        assert!(!has(&m, &Message::Ready));
        assert_eq!(status(&m), Some("waiting for telemetry (frames flow)"));
        // Both.
        let m = p.tick(t0 + Duration::from_secs(6), FRESH);
        assert!(has(&m, &Message::Ready));
        assert!(!m.iter().any(|m| matches!(m, Message::ExtendTimeout(_))));
        // Once.
        p.frame_processed(t0 + Duration::from_secs(7), 0);
        assert!(!has(
            &p.tick(t0 + Duration::from_secs(7), FRESH),
            &Message::Ready
        ));
    }

    #[test]
    fn an_old_frame_does_not_make_it_ready() {
        let t0 = Instant::now();
        let mut p = Plan::new(None);
        p.frame_processed(t0, 0);
        let m = p.tick(t0 + FRAMES_FLOW_WITHIN + Duration::from_millis(1), FRESH);
        assert!(!has(&m, &Message::Ready));
    }

    #[test]
    fn watchdog_pings_follow_processed_frames_only() {
        let t0 = Instant::now();
        let mut p = Plan::new(Some(Duration::from_secs(2)));
        p.frame_processed(t0, 1);
        assert!(has(&p.tick(t0, FRESH), &Message::Ready));
        let mut pings = Vec::new();
        // Frames at 10 Hz for 5 s: a ping every second (half the interval).
        for k in 1..=50 {
            let now = t0 + Duration::from_millis(100 * k);
            p.frame_processed(now, 1);
            if has(&p.tick(now, FRESH), &Message::Watchdog) {
                pings.push(k);
            }
        }
        assert_eq!(pings, vec![10, 20, 30, 40, 50]);
        // Then the frames stop: the loop still turns, no more pings.
        for k in 51..=150 {
            let m = p.tick(t0 + Duration::from_millis(100 * k), FRESH);
            assert!(!has(&m, &Message::Watchdog), "ping at {k} without frames");
        }
        let m = p.tick(t0 + Duration::from_secs(16), FRESH);
        assert_eq!(status(&m), Some("no frames for 11 s"));
        // Frames again: pings again.
        p.frame_processed(t0 + Duration::from_secs(17), 1);
        assert!(has(
            &p.tick(t0 + Duration::from_secs(17), FRESH),
            &Message::Watchdog
        ));
    }

    #[test]
    fn no_watchdog_means_no_pings_and_a_fixed_extension() {
        let t0 = Instant::now();
        let mut p = Plan::new(None);
        assert!(has(
            &p.tick(t0, STALE),
            &Message::ExtendTimeout(EXTEND_WITHOUT_WATCHDOG)
        ));
        p.frame_processed(t0, 0);
        assert!(has(&p.tick(t0, FRESH), &Message::Ready));
        for k in 1..=100 {
            let now = t0 + Duration::from_millis(100 * k);
            p.frame_processed(now, 0);
            assert!(!has(&p.tick(now, FRESH), &Message::Watchdog));
        }
    }

    #[test]
    fn status_counts_tracks_and_frame_rate() {
        let t0 = Instant::now();
        let mut p = Plan::new(Some(Duration::from_secs(10)));
        p.frame_processed(t0, 3);
        assert!(has(&p.tick(t0, FRESH), &Message::Ready));
        let mut last = None;
        for k in 1..=60 {
            let now = t0 + Duration::from_millis(1000 * k / 30);
            p.frame_processed(now, 3);
            if let Some(s) = status(&p.tick(now, FRESH)) {
                last = Some(s.to_owned());
            }
        }
        assert_eq!(last.as_deref(), Some("tracking: 3 tracks, 30 fps"));
        let now = t0 + Duration::from_millis(2100);
        p.frame_processed(now, 2);
        let later = now + STATUS_EVERY;
        p.frame_processed(later, 2);
        let m = p.tick(later, STALE);
        assert!(
            status(&m).is_some_and(|s| s.starts_with("tracking: 2 tracks")
                && s.ends_with("telemetry lost (tracking in the image only)"))
        );
    }
}
