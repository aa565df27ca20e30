//! Between the link and the pipeline: MAVLink in, domain events out ([`Inbox`]); domain
//! outputs in, MAVLink out ([`Outputs`]). The pipeline names no MAVLink type: it receives
//! [`LinkInput`]s (telemetry updates, operator requests) and hands over core values
//! ([`TrackReport`], [`TrackingStatus`], [`Notice`]).
//!
//! What needs no decision by the pipeline is answered here: unsigned commands refused when
//! signing is on, CAMERA_INFORMATION requests (from the latest frame size the pipeline set),
//! commands mgmot does not implement.

use super::decode::{decode, decode_mount_status, CameraCommand, Incoming};
use super::dialect::MavCmd;
use super::encode::{
    camera_fov_status, camera_information, camera_tracking_geo_status,
    camera_tracking_geo_status_lost, camera_tracking_image_status,
    camera_tracking_image_status_lost, command_ack, heartbeat, mgmot_track, statustext,
    target_absolute, AckResult, Severity,
};
use super::link::{Link, LinkError, LinkEvent, LinkSender, LinkSettings, OnSent, Received};
use crate::geo::{CameraView, Geodetic};
use crate::health::{Level, Notice};
use crate::logging::LogThrottle;
use crate::operator::{CommandResult, Request};
use crate::report::{TrackReport, TrackingMode, TrackingStatus};
use crate::telemetry::{
    AttitudeSample, AutopilotTimeUs, CompanionTimeUs, GimbalSample, PositionFix,
};
use std::num::NonZeroU16;
use std::sync::atomic::{AtomicU16, AtomicU64, Ordering};
use std::sync::Arc;
use tokio::sync::mpsc;

/// A telemetry update for the pose buffer and the clock mapping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TelemetryUpdate {
    /// The vehicle's position (GLOBAL_POSITION_INT), arrived at `at`.
    Position {
        /// The sample, on the autopilot clock, with its velocity.
        fix: PositionFix,
        /// Arrival time.
        at: CompanionTimeUs,
    },
    /// The vehicle's attitude (ATTITUDE), arrived at `at`.
    Attitude {
        /// The sample, on the autopilot clock.
        sample: AttitudeSample,
        /// Arrival time.
        at: CompanionTimeUs,
    },
    /// The gimbal's attitude with a time of its own (GIMBAL_DEVICE_ATTITUDE_STATUS,
    /// MOUNT_ORIENTATION).
    Gimbal {
        /// The attitude (normalised).
        sample: GimbalSample,
        /// The quaternion's norm as sent (`None`: sent as angles).
        quaternion_norm: Option<f64>,
        /// Arrival time.
        at: CompanionTimeUs,
    },
    /// A gimbal attitude without a time of its own (MOUNT_STATUS): its `time` is to be the
    /// arrival time `at` on the autopilot clock, once that clock is known.
    GimbalAtArrival {
        /// The attitude (its `time` is not meaningful).
        sample: GimbalSample,
        /// Arrival time.
        at: CompanionTimeUs,
    },
    /// The home position (HOME_POSITION; altitude AMSL).
    Home(Geodetic),
    /// The GNSS receiver's horizontal accuracy (GPS_RAW_INT `h_acc`, with a fix), arrived at
    /// `at`.
    GnssAccuracy {
        /// Horizontal accuracy (m).
        h_acc_m: f64,
        /// Arrival time.
        at: CompanionTimeUs,
    },
    /// A TIMESYNC round trip answering one of our requests.
    TimeSync {
        /// Our request's companion time.
        sent: CompanionTimeUs,
        /// The autopilot's time in its answer.
        autopilot: AutopilotTimeUs,
        /// When the answer arrived.
        at: CompanionTimeUs,
    },
}

/// Who to answer, and what: a command's sender and number (opaque to the pipeline).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplyTo {
    mav_cmd: MavCmd,
    system: u8,
    component: u8,
}

/// An operator's camera-tracking request; answer it with [`Outputs::command_result`] (or
/// [`Outputs::command_busy`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatorRequest {
    /// What is asked.
    pub request: Request,
    /// Where the answer goes.
    pub reply: ReplyTo,
}

/// What the link hands the pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinkInput {
    /// Telemetry from the autopilot or the vehicle's gimbal.
    Telemetry(TelemetryUpdate),
    /// An operator's camera-tracking command.
    Operator(OperatorRequest),
}

/// Starts the link and returns it with its two domain ends. `target_absolute`: whether each
/// geolocated track report is also sent as TARGET_ABSOLUTE.
pub fn start(
    settings: LinkSettings,
    target_absolute: bool,
) -> Result<(Link, Inbox, Outputs), LinkError> {
    let (system_id, component_id) = (settings.system_id, settings.component_id);
    let commands_need_signature = settings.signing.is_some();
    let (link, sender, events) = Link::start(settings)?;
    let outputs = Outputs {
        sender,
        frame_size: Arc::new(FrameSize::default()),
        target_absolute,
        statustext_id: Arc::new(AtomicU16::new(0)),
    };
    let inbox = Inbox {
        events,
        outputs: outputs.clone(),
        system_id,
        component_id,
        commands_need_signature,
        unsigned_log: LogThrottle::default(),
    };
    Ok((link, inbox, outputs))
}

/// The link's incoming side, as domain events.
#[derive(Debug)]
pub struct Inbox {
    events: mpsc::Receiver<LinkEvent>,
    outputs: Outputs,
    system_id: u8,
    component_id: u8,
    commands_need_signature: bool,
    /// "Unsigned command refused" is logged at most every `LOG_EVERY`.
    unsigned_log: LogThrottle,
}

impl Inbox {
    /// The next event for the pipeline; `None` once the link has stopped.
    pub async fn recv(&mut self) -> Option<LinkInput> {
        loop {
            let received = match self.events.recv().await? {
                LinkEvent::TimeSync {
                    sent,
                    autopilot,
                    at,
                } => {
                    return Some(LinkInput::Telemetry(TelemetryUpdate::TimeSync {
                        sent,
                        autopilot,
                        at,
                    }))
                }
                LinkEvent::Message(r) => *r,
            };
            if let Some(input) = self.translate(&received) {
                return Some(input);
            }
        }
    }

    /// One message: telemetry and operator requests go to the pipeline, the rest is answered
    /// here or ignored.
    fn translate(&mut self, r: &Received) -> Option<LinkInput> {
        let at = r.at;
        if let Some(sample) = decode_mount_status(&r.message, AutopilotTimeUs(0)) {
            return Some(LinkInput::Telemetry(TelemetryUpdate::GimbalAtArrival {
                sample,
                at,
            }));
        }
        let telemetry = |u| Some(LinkInput::Telemetry(u));
        match decode(
            &r.message,
            r.component_id,
            self.system_id,
            self.component_id,
        )? {
            Incoming::Position(fix) => telemetry(TelemetryUpdate::Position { fix, at }),
            Incoming::Attitude(sample) => telemetry(TelemetryUpdate::Attitude { sample, at }),
            Incoming::Gimbal {
                sample,
                quaternion_norm,
            } => telemetry(TelemetryUpdate::Gimbal {
                sample,
                quaternion_norm,
                at,
            }),
            Incoming::Home(h) => telemetry(TelemetryUpdate::Home(h)),
            Incoming::GnssAccuracy { h_acc_m } => {
                telemetry(TelemetryUpdate::GnssAccuracy { h_acc_m, at })
            }
            c if c.is_command() => self.command(c, r),
            _ => None,
        }
    }

    /// A command: refused unsigned (when signing is on), answered here, or handed on.
    fn command(&mut self, c: Incoming, r: &Received) -> Option<LinkInput> {
        let reply = ReplyTo {
            mav_cmd: c.mav_cmd()?,
            system: r.system_id,
            component: r.component_id,
        };
        if self.commands_need_signature && !r.signed {
            if let Some(suppressed) = self.unsigned_log.allow() {
                tracing::warn!(
                    from_system = r.system_id,
                    from_component = r.component_id,
                    suppressed,
                    "unsigned command refused (signing is on)"
                );
            }
            self.outputs.ack(reply, AckResult::Denied);
            return None;
        }
        match c {
            Incoming::Command { command, .. } => Some(LinkInput::Operator(OperatorRequest {
                request: operator_request(command),
                reply,
            })),
            Incoming::CameraInformationRequest => {
                self.outputs.ack(reply, AckResult::Accepted);
                let boot_ms = u32::try_from(r.at.0 / 1000).unwrap_or(u32::MAX);
                self.outputs
                    .sender
                    .send(camera_information(boot_ms, self.outputs.frame_size.get()));
                None
            }
            Incoming::UnsupportedCommand { .. } => {
                self.outputs.ack(reply, AckResult::Unsupported);
                None
            }
            _ => None,
        }
    }
}

fn operator_request(c: CameraCommand) -> Request {
    match c {
        CameraCommand::TrackPoint { x, y, radius } => Request::Point {
            x: f64::from(x),
            y: f64::from(y),
            radius: Some(f64::from(radius)),
        },
        CameraCommand::TrackRectangle { x0, y0, x1, y1 } => Request::Rectangle {
            x0: f64::from(x0),
            y0: f64::from(y0),
            x1: f64::from(x1),
            y1: f64::from(y1),
        },
        CameraCommand::Stop => Request::Stop,
    }
}

/// The link's outgoing side, from domain values (cheap to clone). Nothing here blocks: when
/// the link's queue is full, messages are dropped and counted ([`Outputs::dropped`]).
#[derive(Debug, Clone)]
pub struct Outputs {
    sender: LinkSender,
    frame_size: Arc<FrameSize>,
    target_absolute: bool,
    /// The last id of a chunked STATUSTEXT: ground stations join chunks by id, so each long
    /// notice needs one of its own (shared by the clones).
    statustext_id: Arc<AtomicU16>,
}

impl Outputs {
    /// HEARTBEAT.
    pub fn heartbeat(&self) {
        self.sender.send(heartbeat());
    }

    /// A notice for the operator, as STATUSTEXT (in chunks when longer than 50 bytes, see
    /// [`statustext`]).
    pub fn notice(&self, notice: &Notice) {
        let severity = match notice.level {
            Level::Info => Severity::Info,
            Level::Notice => Severity::Notice,
            Level::Warning => Severity::Warning,
        };
        for m in statustext(severity, &notice.text, self.next_statustext_id()) {
            self.sender.send(m);
        }
    }

    /// 1, 2, ... 65535, 1, ...: never 0, which means "not chunked".
    fn next_statustext_id(&self) -> NonZeroU16 {
        let mut id = NonZeroU16::MIN;
        let _ = self
            .statustext_id
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |last| {
                id = NonZeroU16::new(last.wrapping_add(1)).unwrap_or(NonZeroU16::MIN);
                Some(id.get())
            });
        id
    }

    /// A track report: MGMOT_TRACK (then `on_sent` is called with the time it reached the
    /// socket), and TARGET_ABSOLUTE when configured and the track is geolocated.
    pub fn track(&self, report: &TrackReport, on_sent: OnSent) {
        self.sender.send_then(mgmot_track(report), on_sent);
        if self.target_absolute {
            if let Some(m) = target_absolute(report) {
                self.sender.send(m);
            }
        }
    }

    /// Where the camera is and looks (CAMERA_FOV_STATUS), for a ground station's footprint:
    /// see [`camera_fov_status`].
    pub fn camera_fov(&self, time: AutopilotTimeUs, view: &CameraView, centre: Option<&Geodetic>) {
        self.sender.send(camera_fov_status(time, view, centre));
    }

    /// The operator-selected track's status (CAMERA_TRACKING_IMAGE_STATUS and
    /// CAMERA_TRACKING_GEO_STATUS), or "not tracking" (`None`).
    pub fn tracking_status(&self, status: Option<&TrackingStatus>) {
        self.sender.send(camera_tracking_image_status(status));
        self.sender.send(camera_tracking_geo_status(status));
    }

    /// The status of a selection whose track is lost, waiting for re-identification
    /// (CAMERA_TRACKING_IMAGE_STATUS and CAMERA_TRACKING_GEO_STATUS: ACTIVE | ERROR, no
    /// target).
    pub fn tracking_lost(&self, mode: TrackingMode) {
        self.sender.send(camera_tracking_image_status_lost(mode));
        self.sender.send(camera_tracking_geo_status_lost());
    }

    /// Answers an operator request (COMMAND_ACK).
    pub fn command_result(&self, reply: ReplyTo, result: CommandResult) {
        self.ack(
            reply,
            match result {
                CommandResult::Accepted => AckResult::Accepted,
                CommandResult::Denied => AckResult::Denied,
                CommandResult::Failed => AckResult::Failed,
            },
        );
    }

    /// Answers an operator request that could not be queued: try again (COMMAND_ACK
    /// TEMPORARILY_REJECTED).
    pub fn command_busy(&self, reply: ReplyTo) {
        self.ack(reply, AckResult::TemporarilyRejected);
    }

    /// The latest frame's size (px), for CAMERA_INFORMATION.
    pub fn set_frame_size(&self, size: (u32, u32)) {
        self.frame_size.set(size);
    }

    /// Messages dropped because the link's queue was full.
    pub fn dropped(&self) -> u64 {
        self.sender.dropped()
    }

    fn ack(&self, reply: ReplyTo, result: AckResult) {
        self.sender.send(command_ack(
            reply.mav_cmd,
            result,
            reply.system,
            reply.component,
        ));
    }
}

/// A frame size shared between threads, `(width << 32) | height` (0: none yet).
#[derive(Debug, Default)]
struct FrameSize(AtomicU64);

impl FrameSize {
    fn set(&self, (w, h): (u32, u32)) {
        self.0
            .store((u64::from(w) << 32) | u64::from(h), Ordering::Relaxed);
    }

    fn get(&self) -> Option<(u32, u32)> {
        let v = self.0.load(Ordering::Relaxed);
        (v != 0).then_some(((v >> 32) as u32, v as u32))
    }
}
