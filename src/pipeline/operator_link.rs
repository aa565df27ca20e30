//! The frame step's side of operator tracking: the queue of operator requests from the link,
//! the selection ([`crate::operator`]), and the timing of the selected track's status.

use crate::frame::GeoFix;
use crate::health::{Level, Notice};
use crate::mavlink::{OperatorRequest, Outputs};
use crate::operator::{Candidate, Change, Mode, Outcome, Presence, Selection};
use crate::report::{TrackingMode, TrackingStatus};
use crate::track::{FrameOutput, TrackOutput, Tracker};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// Operator tracking on the frame-step thread.
pub(super) struct OperatorLink {
    /// Requests from the link's receive task.
    requests: Receiver<OperatorRequest>,
    /// Which track is selected.
    selection: Selection,
    /// The confirmed tracks of the latest frame: what a command can select.
    candidates: Vec<Candidate>,
    /// The latest frame's size (px); `None` before the first frame.
    image_size_px: Option<(u32, u32)>,
    /// Time between status messages of the selected track.
    status_every: Duration,
    /// When status was last sent (`None`: send at the next frame).
    last_status: Option<Instant>,
    outputs: Outputs,
}

impl OperatorLink {
    /// `point_radius`: the default click radius; `status_every`: time between status messages.
    pub fn new(
        requests: Receiver<OperatorRequest>,
        point_radius: f64,
        status_every: Duration,
        outputs: Outputs,
    ) -> Self {
        Self {
            requests,
            selection: Selection::new(point_radius),
            candidates: Vec::new(),
            image_size_px: None,
            status_every,
            last_status: None,
            outputs,
        }
    }

    /// Answers every queued request against the latest tracks.
    pub fn answer_requests(&mut self) {
        while let Ok(r) = self.requests.try_recv() {
            let outcome = self
                .selection
                .command(&r.request, &self.candidates, self.image_size_px);
            tracing::info!(request = ?r.request, ?outcome, "operator command");
            self.outputs.command_result(r.reply, outcome.result());
            match outcome {
                Outcome::Selected { .. } => self.last_status = None,
                Outcome::Stopped { .. } => self.outputs.tracking_status(None),
                Outcome::Refused(_) => {}
            }
        }
    }

    /// After a tracker step: keep the selection on its track (merges; lost while only the
    /// tracker's ReID memory keeps it, restored when ReID brings it back, ended when the
    /// memory gives up on it), answer the queued requests against this frame's tracks, and
    /// send the selected track's status when due. `geo` gives a track's fix and distance from the camera.
    pub fn after_step(
        &mut self,
        output: &FrameOutput,
        tracker: &Tracker,
        image_size_px: (u32, u32),
        geo: impl Fn(&TrackOutput) -> (Option<GeoFix>, Option<f64>),
    ) {
        if self.image_size_px != Some(image_size_px) {
            self.outputs.set_frame_size(image_size_px);
        }
        self.image_size_px = Some(image_size_px);
        self.candidates.clear();
        self.candidates
            .extend(output.tracks.iter().map(|t| Candidate {
                id: t.id,
                bbox: t.bbox,
            }));
        match self
            .selection
            .follow(&output.merges, |id| Presence::of(tracker, id))
        {
            Some(Change::Ended { track_id }) => {
                tracing::warn!(track = track_id, "selected track removed: tracking stopped");
                self.outputs.notice(&Notice::new(
                    Level::Warning,
                    format!("mgmot: track {track_id} gone, tracking stopped"),
                ));
                self.outputs.tracking_status(None);
            }
            Some(Change::Lost { track_id }) => {
                tracing::warn!(
                    track = track_id,
                    "selected track lost: kept until ReID brings it back"
                );
                self.outputs.notice(&Notice::new(
                    Level::Warning,
                    format!("mgmot: track {track_id} lost, awaiting ReID"),
                ));
                self.last_status = None;
            }
            Some(Change::Restored { track_id }) => {
                tracing::info!(track = track_id, "selected track back (ReID)");
                self.outputs.notice(&Notice::new(
                    Level::Notice,
                    format!("mgmot: track {track_id} back, tracking"),
                ));
                self.last_status = None;
            }
            None => {}
        }
        self.answer_requests();
        let Some(selected) = self.selection.selected() else {
            return;
        };
        if self
            .last_status
            .is_some_and(|at| at.elapsed() < self.status_every)
        {
            return;
        }
        let mode = match selected.mode {
            Mode::Point => TrackingMode::Point,
            Mode::Rectangle => TrackingMode::Rectangle,
        };
        if selected.lost {
            // Out of the tracker, in its ReID memory: no box, no position.
            self.outputs.tracking_lost(mode);
            self.last_status = Some(Instant::now());
            return;
        }
        // A confirmed track of this frame, or (lost for now) the tracker's prediction.
        let track = output
            .tracks
            .iter()
            .find(|t| t.id == selected.track_id)
            .copied()
            .or_else(|| tracker.live_tracks().find(|t| t.id == selected.track_id));
        let Some(t) = track else {
            return;
        };
        let (fix, range_m) = geo(&t);
        let status = TrackingStatus::new(mode, &t, image_size_px, fix, range_m);
        self.outputs.tracking_status(Some(&status));
        self.last_status = Some(Instant::now());
    }
}
