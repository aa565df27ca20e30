//! Which telemetry streams the autopilot has been asked for, which flow, and when to ask again.
//!
//! Autopilots start with some streams off (ArduCopter's default stream rates are 0) and forget
//! every SET_MESSAGE_INTERVAL when they reboot; a request sent before the autopilot has heard
//! from us (UDP) is lost. So a stream is asked for once the autopilot is known to be there, one
//! request outstanding at a time (a COMMAND_ACK does not say which message it answers), and
//! again whenever it stops flowing, with a back-off; a stream the autopilot refuses (DENIED,
//! UNSUPPORTED, FAILED) is not asked for again until it reboots.
//!
//! Some streams a type of autopilot is known not to send ([`not_sent_by`]): ArduPilot refuses
//! MOUNT_ORIENTATION, and tells the operator's ground station "No ap_message for mavlink id
//! (265)" each time it is asked. Such a stream waits for the autopilot's HEARTBEAT, which
//! names its type, and is not asked of an autopilot known not to send it. Pure: times and the
//! autopilot's type are passed in.

#[allow(deprecated)] // MOUNT_ORIENTATION: deprecated in common.xml, still sent by some gimbals
use crate::mavlink::dialect::{MavAutopilot, MOUNT_ORIENTATION_DATA};
use mavlink_core::MessageData;
use std::time::Duration;

/// How long to wait for the COMMAND_ACK of one request before sending the next.
pub const ACK_TIMEOUT: Duration = Duration::from_millis(1000);
/// First wait before asking again for a stream that does not flow.
pub const RETRY_INITIAL: Duration = Duration::from_secs(2);
/// Longest wait between two requests for a stream that does not flow.
pub const RETRY_MAX: Duration = Duration::from_secs(30);

/// A stream's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamState {
    /// Not asked for yet (or to be asked again).
    Wanted,
    /// Asked for at the given time; flowing once messages arrive.
    Requested,
    /// The autopilot answered the request with a refusal.
    Refused,
    /// Not asked: the autopilot's type is known not to send it ([`not_sent_by`]).
    NotSent,
}

/// The streams an autopilot of type `autopilot` (its HEARTBEAT's `autopilot` field) is known
/// not to send, whatever it is asked.
#[allow(deprecated)] // MOUNT_ORIENTATION: deprecated in common.xml, still sent by some gimbals
pub fn not_sent_by(autopilot: MavAutopilot) -> &'static [u32] {
    match autopilot {
        // Upstream 90700977c5 on SITL: DENIED, "No ap_message for mavlink id (265)".
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA => &[MOUNT_ORIENTATION_DATA::ID],
        _ => &[],
    }
}

/// Whether some type of autopilot does not send `message_id`: its request waits for the
/// autopilot's type.
fn depends_on_autopilot_type(message_id: u32) -> bool {
    [MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA]
        .into_iter()
        .any(|a| not_sent_by(a).contains(&message_id))
}

#[derive(Debug, Clone)]
struct Stream {
    message_id: u32,
    rate_hz: f32,
    state: StreamState,
    last_seen: Option<Duration>,
    next_request: Duration,
    retry: Duration,
    /// Ask even if messages flow: at the start and after a reboot the autopilot may send the
    /// stream at its own default rate, not the one asked for.
    force: bool,
}

/// The request bookkeeping of every stream. Times are durations since the link started.
#[derive(Debug, Clone)]
pub struct StreamRequests {
    streams: Vec<Stream>,
    /// The stream whose request is waiting for its COMMAND_ACK, and when it was sent.
    outstanding: Option<(usize, Duration)>,
    /// The autopilot's type, once its HEARTBEAT has been heard.
    autopilot: Option<MavAutopilot>,
}

/// A request to send now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    /// Message id.
    pub message_id: u32,
    /// Rate asked for (Hz).
    pub rate_hz: f32,
}

/// The result of a SET_MESSAGE_INTERVAL, as the COMMAND_ACK said.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AckOutcome {
    /// MAV_RESULT_ACCEPTED (or IN_PROGRESS).
    Accepted,
    /// Refused for good (DENIED, UNSUPPORTED, FAILED).
    Refused,
    /// TEMPORARILY_REJECTED or anything else: ask again later.
    Retry,
}

impl StreamRequests {
    /// Bookkeeping for `(message id, rate Hz)` streams, none asked for yet.
    pub fn new(streams: &[(u32, f32)]) -> Self {
        Self {
            streams: streams
                .iter()
                .map(|&(message_id, rate_hz)| Stream {
                    message_id,
                    rate_hz,
                    state: StreamState::Wanted,
                    last_seen: None,
                    next_request: Duration::ZERO,
                    retry: RETRY_INITIAL,
                    force: true,
                })
                .collect(),
            outstanding: None,
            autopilot: None,
        }
    }

    /// The autopilot's HEARTBEAT named its type: the streams it is known not to send are
    /// not asked for (the others are unaffected; the type outlives reboots).
    pub fn autopilot_type(&mut self, autopilot: MavAutopilot) {
        if self.autopilot == Some(autopilot) {
            return;
        }
        self.autopilot = Some(autopilot);
        let not_sent = not_sent_by(autopilot);
        for (i, s) in self.streams.iter_mut().enumerate() {
            if not_sent.contains(&s.message_id) {
                s.state = StreamState::NotSent;
                if self.outstanding.is_some_and(|(o, _)| o == i) {
                    self.outstanding = None;
                }
            } else if s.state == StreamState::NotSent {
                s.state = StreamState::Wanted;
            }
        }
    }

    /// A stream counts as flowing when a message arrived within this window: three periods,
    /// at least 3 s.
    fn window(rate_hz: f32) -> Duration {
        let period = if rate_hz > 0.0 {
            Duration::from_secs_f64((3.0 / f64::from(rate_hz)).min(3600.0))
        } else {
            Duration::ZERO
        };
        period.max(Duration::from_secs(3))
    }

    /// A message with `message_id` arrived from the autopilot at `now`.
    pub fn seen(&mut self, message_id: u32, now: Duration) {
        for s in self
            .streams
            .iter_mut()
            .filter(|s| s.message_id == message_id)
        {
            s.last_seen = Some(now);
            s.retry = RETRY_INITIAL;
        }
    }

    /// The autopilot answered the outstanding request.
    pub fn ack(&mut self, outcome: AckOutcome, now: Duration) {
        let Some((i, _)) = self.outstanding.take() else {
            return;
        };
        let s = &mut self.streams[i];
        match outcome {
            AckOutcome::Accepted => s.state = StreamState::Requested,
            AckOutcome::Refused => s.state = StreamState::Refused,
            AckOutcome::Retry => {
                s.state = StreamState::Wanted;
                s.next_request = now + s.retry;
            }
        }
    }

    /// The autopilot rebooted (or came back after silence): it forgot every request.
    pub fn reset(&mut self, now: Duration) {
        self.outstanding = None;
        for s in self
            .streams
            .iter_mut()
            .filter(|s| s.state != StreamState::NotSent)
        {
            s.state = StreamState::Wanted;
            s.last_seen = None;
            s.next_request = now;
            s.retry = RETRY_INITIAL;
            s.force = true;
        }
    }

    /// Whether the stream with `message_id` was refused by the autopilot.
    pub fn state(&self, message_id: u32) -> Option<StreamState> {
        self.streams
            .iter()
            .find(|s| s.message_id == message_id)
            .map(|s| s.state)
    }

    /// Whether a message of the stream arrived recently enough to call it flowing.
    pub fn flowing(&self, message_id: u32, now: Duration) -> bool {
        self.streams.iter().any(|s| {
            s.message_id == message_id
                && s.last_seen
                    .is_some_and(|t| now.saturating_sub(t) <= Self::window(s.rate_hz))
        })
    }

    /// The request to send at `now`, if any: one at a time, for a stream not flowing whose
    /// back-off has passed. The caller sends it.
    pub fn poll(&mut self, now: Duration) -> Option<Request> {
        if let Some((_, sent)) = self.outstanding {
            if now.saturating_sub(sent) < ACK_TIMEOUT {
                return None;
            }
            // No answer: the request may still have worked; judge it by the messages.
            if let Some((i, _)) = self.outstanding.take() {
                self.streams[i].state = StreamState::Requested;
            }
        }
        let flowing: Vec<bool> = self
            .streams
            .iter()
            .map(|s| {
                s.last_seen
                    .is_some_and(|t| now.saturating_sub(t) <= Self::window(s.rate_hz))
            })
            .collect();
        let type_known = self.autopilot.is_some();
        let (i, s) = self.streams.iter_mut().enumerate().find(|(i, s)| {
            !matches!(s.state, StreamState::Refused | StreamState::NotSent)
                && (type_known || !depends_on_autopilot_type(s.message_id))
                && (s.force || !flowing[*i])
                && now >= s.next_request
        })?;
        s.force = false;
        s.next_request = now + s.retry;
        s.retry = (s.retry * 2).min(RETRY_MAX);
        self.outstanding = Some((i, now));
        Some(Request {
            message_id: s.message_id,
            rate_hz: s.rate_hz,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: fn(u64) -> Duration = Duration::from_millis;

    #[test]
    fn one_request_at_a_time_until_each_stream_flows() {
        let mut r = StreamRequests::new(&[(33, 50.0), (30, 50.0)]);
        let a = r.poll(S(0)).unwrap();
        assert_eq!(a.message_id, 33);
        assert_eq!(r.poll(S(10)), None, "waits for the ack");
        r.ack(AckOutcome::Accepted, S(20));
        let b = r.poll(S(30)).unwrap();
        assert_eq!(b.message_id, 30);
        r.ack(AckOutcome::Accepted, S(40));
        r.seen(33, S(100));
        r.seen(30, S(100));
        assert_eq!(r.poll(S(200)), None, "both flow");
        // 33 stops flowing: asked again after its window and back-off.
        r.seen(30, S(4000));
        assert_eq!(r.poll(S(4000)).map(|q| q.message_id), Some(33));
    }

    #[test]
    fn a_stream_flowing_at_the_autopilot_default_is_still_asked_for_at_start_and_after_a_reboot() {
        let mut r = StreamRequests::new(&[(33, 50.0)]);
        r.seen(33, S(0));
        assert!(r.poll(S(0)).is_some(), "asked at start although it flows");
        r.ack(AckOutcome::Accepted, S(5));
        r.seen(33, S(100));
        assert_eq!(r.poll(S(200)), None);
        r.reset(S(300));
        r.seen(33, S(300));
        assert!(
            r.poll(S(300)).is_some(),
            "asked after the reboot although it flows"
        );
    }

    #[test]
    fn refused_streams_are_not_asked_again_until_a_reboot() {
        let mut r = StreamRequests::new(&[(242, 50.0)]);
        assert!(r.poll(S(0)).is_some());
        r.ack(AckOutcome::Refused, S(5));
        for t in (0..120).map(|s| S(s * 1000)) {
            assert_eq!(r.poll(t), None);
        }
        assert_eq!(r.state(242), Some(StreamState::Refused));
        r.reset(S(120_000));
        assert!(r.poll(S(120_000)).is_some());
    }

    #[test]
    fn mount_orientation_waits_for_the_autopilot_type_and_is_not_asked_of_ardupilot() {
        let mut r = StreamRequests::new(&[(265, 50.0), (33, 50.0)]);
        assert_eq!(r.poll(S(0)).map(|q| q.message_id), Some(33), "265 waits");
        r.ack(AckOutcome::Accepted, S(5));
        assert_eq!(r.poll(S(10)), None);
        r.autopilot_type(MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA);
        for t in (0..120).map(|s| S(s * 1000)) {
            r.seen(33, t);
            assert_eq!(r.poll(t), None);
        }
        assert_eq!(r.state(265), Some(StreamState::NotSent));
        r.reset(S(120_000));
        assert_eq!(r.poll(S(120_000)).map(|q| q.message_id), Some(33));
        r.ack(AckOutcome::Accepted, S(120_005));
        assert_eq!(r.poll(S(120_010)), None, "not asked after a reboot either");

        let mut r = StreamRequests::new(&[(265, 50.0)]);
        assert_eq!(r.poll(S(0)), None);
        r.autopilot_type(MavAutopilot::MAV_AUTOPILOT_PX4);
        assert_eq!(r.poll(S(10)).map(|q| q.message_id), Some(265));
    }

    #[test]
    fn unanswered_requests_back_off_to_the_maximum() {
        let mut r = StreamRequests::new(&[(33, 50.0)]);
        let mut sent = Vec::new();
        for t in (0..600).map(|s| S(s * 1000)) {
            if r.poll(t).is_some() {
                sent.push(t.as_secs());
            }
        }
        let gaps: Vec<u64> = sent.windows(2).map(|w| w[1] - w[0]).collect();
        assert_eq!(&gaps[..4], &[2, 4, 8, 16]);
        assert!(gaps[4..].iter().all(|&g| g == 30), "{gaps:?}");
    }

    #[test]
    fn a_slow_stream_has_a_wider_window() {
        let mut r = StreamRequests::new(&[(242, 0.2)]);
        r.poll(S(0));
        r.ack(AckOutcome::Accepted, S(1));
        r.seen(242, S(10));
        assert!(r.flowing(242, S(14_000)), "15 s window for a 0.2 Hz stream");
        assert!(!r.flowing(242, S(16_000)));
    }
}
