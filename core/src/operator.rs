//! The track an operator selects for camera tracking (MAV_CMD_CAMERA_TRACK_POINT,
//! MAV_CMD_CAMERA_TRACK_RECTANGLE, MAV_CMD_CAMERA_STOP_TRACKING): which track a click or a
//! drawn rectangle means, and keeping that choice frame after frame by track id.
//!
//! Pure and synchronous: the caller hands in the tracker's boxes and merge events and sends
//! whatever MAVLink the outcome calls for.

use crate::track::{BBox, MergeEvent, Tracker};

/// How far from a track's box a click may land and still select it, as a fraction of the
/// image width, when the command gives no radius: about a fingertip on a tablet showing the
/// whole frame.
pub const DEFAULT_POINT_RADIUS: f64 = 0.03;

/// What the operator asked for, in normalised image coordinates (0..1, top-left origin, x as
/// a fraction of the width, y of the height), as the MAVLink commands carry them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// Track what is at a point (MAV_CMD_CAMERA_TRACK_POINT).
    Point {
        /// Horizontal position (0 = left edge).
        x: f64,
        /// Vertical position (0 = top edge).
        y: f64,
        /// How far from the point a track's box may be, as a fraction of the image width;
        /// `None` (or 0): the configured default.
        radius: Option<f64>,
    },
    /// Track what the rectangle shows (MAV_CMD_CAMERA_TRACK_RECTANGLE).
    Rectangle {
        /// Left edge.
        x0: f64,
        /// Top edge.
        y0: f64,
        /// Right edge.
        x1: f64,
        /// Bottom edge.
        y1: f64,
    },
    /// Stop tracking (MAV_CMD_CAMERA_STOP_TRACKING).
    Stop,
}

/// How the selection was made; the status messages report the target the same way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Selected by a point: reported as the box centre and radius.
    Point,
    /// Selected by a rectangle: reported as the box.
    Rectangle,
}

/// A track the operator can select: a confirmed track of the current frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Track id.
    pub id: u64,
    /// Its box in the current frame, px.
    pub bbox: BBox,
}

/// Why a request was not carried out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// A coordinate is not a number in 0..=1, or the rectangle has no area.
    #[error("the point or rectangle is not inside the image (normalised 0..1)")]
    InvalidArea,
    /// No frame has been seen yet, so there is no image to point into.
    #[error("no frame yet")]
    NoFrame,
    /// No confirmed track's box is at the point or within the radius.
    #[error("no track at the point")]
    NothingAtPoint,
    /// No confirmed track's box overlaps the rectangle.
    #[error("no track in the rectangle")]
    NothingInRectangle,
}

impl Refusal {
    /// The COMMAND_ACK result class: `Denied` when the parameters themselves are wrong
    /// (retrying the same command cannot work), `Failed` when nothing is there to track.
    pub fn result(&self) -> CommandResult {
        match self {
            Refusal::InvalidArea => CommandResult::Denied,
            Refusal::NoFrame | Refusal::NothingAtPoint | Refusal::NothingInRectangle => {
                CommandResult::Failed
            }
        }
    }
}

/// The answer to a command, as MAV_RESULT classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandResult {
    /// MAV_RESULT_ACCEPTED.
    Accepted,
    /// MAV_RESULT_DENIED: invalid parameters.
    Denied,
    /// MAV_RESULT_FAILED: valid, but there is nothing to track there.
    Failed,
}

/// What a request did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// Track `track_id` is selected now (it may replace an earlier selection).
    Selected {
        /// The selected track.
        track_id: u64,
        /// How it was selected.
        mode: Mode,
    },
    /// Tracking stopped; `track_id` is what was selected (`None`: nothing was).
    Stopped {
        /// The track that was selected.
        track_id: Option<u64>,
    },
    /// Nothing changed (an earlier selection stays).
    Refused(Refusal),
}

impl Outcome {
    /// The COMMAND_ACK result class of the outcome (stopping when idle is accepted: the
    /// operator's intent, "not tracking", holds).
    pub fn result(&self) -> CommandResult {
        match self {
            Outcome::Selected { .. } | Outcome::Stopped { .. } => CommandResult::Accepted,
            Outcome::Refused(r) => r.result(),
        }
    }
}

/// The current selection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Selected {
    /// The track id, as the tracker reports it now (merges followed).
    pub track_id: u64,
    /// How it was selected.
    pub mode: Mode,
    /// The tracker no longer keeps the track, but its ReID memory does: the selection waits
    /// for re-identification to bring the id back, and has no box or position meanwhile.
    pub lost: bool,
}

/// Where the tracker stands with a track id, as [`Selection::follow`] asks it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Presence {
    /// A track the tracker keeps (tracked, or lost and still predicted) carries the id.
    Live,
    /// No track carries it, but the ReID memory keeps the ended track: a new track may still
    /// be re-identified as it and take the id back.
    Remembered,
    /// Neither: the id will not come back.
    Gone,
}

impl Presence {
    /// Where `tracker` stands with `id` after its last step: a kept track reports it (under
    /// its own id, or provisionally as the old id it may take), else its ReID memory holds it
    /// ([`Tracker::remembers`]), else it is gone.
    pub fn of(tracker: &Tracker, id: u64) -> Self {
        if tracker.live_tracks().any(|t| t.id == id) {
            Presence::Live
        } else if tracker.remembers(id) {
            Presence::Remembered
        } else {
            Presence::Gone
        }
    }
}

/// What a tracker step did to the selection ([`Selection::follow`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Change {
    /// The selected track is lost: kept until re-identification brings it back or the ReID
    /// memory gives up on it.
    Lost {
        /// The selected track.
        track_id: u64,
    },
    /// A lost selection's track is back (re-identified), under the same id.
    Restored {
        /// The selected track.
        track_id: u64,
    },
    /// The selection ended: the track can no longer come back.
    Ended {
        /// The track that was selected.
        track_id: u64,
    },
}

/// The operator's selection, kept across frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Radius used for a point command that gives none (fraction of the image width).
    default_radius: f64,
    /// The selected track, if any.
    selected: Option<Selected>,
}

impl Selection {
    /// No selection; point commands without a radius use `default_radius` (fraction of the
    /// image width; a non-finite or negative value counts as 0: the point must be in a box).
    pub fn new(default_radius: f64) -> Self {
        Self {
            default_radius: if default_radius.is_finite() {
                default_radius.max(0.0)
            } else {
                0.0
            },
            selected: None,
        }
    }

    /// The current selection.
    pub fn selected(&self) -> Option<Selected> {
        self.selected
    }

    /// Applies a request against the confirmed tracks of the current frame, whose image is
    /// `image_size_px` (width, height; `None` before the first frame).
    pub fn command(
        &mut self,
        request: &Request,
        tracks: &[Candidate],
        image_size_px: Option<(u32, u32)>,
    ) -> Outcome {
        let picked = match (*request, image_size_px) {
            (Request::Stop, _) => {
                let track_id = self.selected.take().map(|s| s.track_id);
                return Outcome::Stopped { track_id };
            }
            (_, None) => Err(Refusal::NoFrame),
            (Request::Point { x, y, radius }, Some(size)) => {
                let radius = radius.filter(|r| *r > 0.0).unwrap_or(self.default_radius);
                pick_at_point(x, y, radius, tracks, size).map(|id| (id, Mode::Point))
            }
            (Request::Rectangle { x0, y0, x1, y1 }, Some(size)) => {
                pick_in_rectangle([x0, y0, x1, y1], tracks, size).map(|id| (id, Mode::Rectangle))
            }
        };
        match picked {
            Ok((track_id, mode)) => {
                self.selected = Some(Selected {
                    track_id,
                    mode,
                    lost: false,
                });
                Outcome::Selected { track_id, mode }
            }
            Err(r) => Outcome::Refused(r),
        }
    }

    /// Keeps the selection on its track after a tracker step: follows re-identification merges
    /// (the selected id was a new track that turned out to be an old one and carries the old
    /// id now), then asks `presence` where the tracker stands with the id. A track no longer
    /// kept but still in the ReID memory leaves the selection lost (not ended): when a merge
    /// brings the id back it is restored; when the memory gives up on it, it ends. Returns
    /// what changed.
    pub fn follow(
        &mut self,
        merges: &[MergeEvent],
        presence: impl Fn(u64) -> Presence,
    ) -> Option<Change> {
        let sel = self.selected.as_mut()?;
        for m in merges {
            if m.new_id == sel.track_id {
                sel.track_id = m.merged_into_id;
            }
        }
        let track_id = sel.track_id;
        match (presence(track_id), sel.lost) {
            (Presence::Live, false) | (Presence::Remembered, true) => None,
            (Presence::Live, true) => {
                sel.lost = false;
                Some(Change::Restored { track_id })
            }
            (Presence::Remembered, false) => {
                sel.lost = true;
                Some(Change::Lost { track_id })
            }
            (Presence::Gone, _) => {
                self.selected = None;
                Some(Change::Ended { track_id })
            }
        }
    }
}

fn in_unit(v: f64) -> bool {
    v.is_finite() && (0.0..=1.0).contains(&v)
}

/// The track at a point: the box containing it, or failing that the nearest box within
/// `radius` (fraction of the image width); among several, the one whose centre is nearest,
/// then the lowest id (deterministic whatever the order of `tracks`).
fn pick_at_point(
    x: f64,
    y: f64,
    radius: f64,
    tracks: &[Candidate],
    (w, h): (u32, u32),
) -> Result<u64, Refusal> {
    if !in_unit(x) || !in_unit(y) || !radius.is_finite() || radius < 0.0 {
        return Err(Refusal::InvalidArea);
    }
    let (w, h) = (f64::from(w), f64::from(h));
    let (px, py) = (x * w, y * h);
    let radius_px = radius * w;
    tracks
        .iter()
        .filter(|t| t.bbox.is_valid())
        .map(|t| {
            let b = &t.bbox;
            let dx = (b.x - px).max(px - (b.x + b.w)).max(0.0);
            let dy = (b.y - py).max(py - (b.y + b.h)).max(0.0);
            let (cx, cy) = b.center();
            (dx.hypot(dy), (cx - px).hypot(cy - py), t.id)
        })
        .filter(|(to_box, _, _)| *to_box <= radius_px)
        .min_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1.total_cmp(&b.1))
                .then(a.2.cmp(&b.2))
        })
        .map(|(_, _, id)| id)
        .ok_or(Refusal::NothingAtPoint)
}

/// The track a rectangle means: the overlapping box with the highest IoU, then the largest
/// overlap, then the lowest id. Corners may come in any order.
fn pick_in_rectangle(
    corners: [f64; 4],
    tracks: &[Candidate],
    (w, h): (u32, u32),
) -> Result<u64, Refusal> {
    if !corners.iter().all(|v| in_unit(*v)) {
        return Err(Refusal::InvalidArea);
    }
    let [x0, y0, x1, y1] = corners;
    let (w, h) = (f64::from(w), f64::from(h));
    let rect = BBox::new(
        x0.min(x1) * w,
        y0.min(y1) * h,
        (x1 - x0).abs() * w,
        (y1 - y0).abs() * h,
    );
    if !rect.is_valid() {
        return Err(Refusal::InvalidArea);
    }
    tracks
        .iter()
        .filter(|t| t.bbox.is_valid())
        .map(|t| {
            let iou = rect.iou(&t.bbox);
            let overlap = iou * (rect.area() + t.bbox.area()) / (1.0 + iou);
            (iou, overlap, t.id)
        })
        .filter(|(iou, _, _)| *iou > 0.0)
        .max_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1.total_cmp(&b.1))
                .then(b.2.cmp(&a.2))
        })
        .map(|(_, _, id)| id)
        .ok_or(Refusal::NothingInRectangle)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::{Detection, FrameInput, TrackerParams, WorldObservation};
    use nalgebra::{Matrix2, Vector2};
    use proptest::prelude::*;

    const SIZE: (u32, u32) = (1000, 500);

    fn track(id: u64, x: f64, y: f64, w: f64, h: f64) -> Candidate {
        Candidate {
            id,
            bbox: BBox::new(x, y, w, h),
        }
    }

    fn point(x: f64, y: f64) -> Request {
        Request::Point { x, y, radius: None }
    }

    fn merge(new_id: u64, merged_into_id: u64) -> MergeEvent {
        MergeEvent {
            new_id,
            merged_into_id,
            frame_index: 0,
        }
    }

    #[test]
    fn a_point_inside_a_box_selects_it() {
        let tracks = [
            track(3, 100.0, 100.0, 20.0, 10.0),
            track(4, 500.0, 250.0, 20.0, 10.0),
        ];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        let o = s.command(&point(0.51, 0.51), &tracks, Some(SIZE));
        assert_eq!(
            o,
            Outcome::Selected {
                track_id: 4,
                mode: Mode::Point
            }
        );
        assert_eq!(o.result(), CommandResult::Accepted);
        assert_eq!(s.selected().map(|s| s.track_id), Some(4));
    }

    #[test]
    fn overlapping_boxes_go_to_the_nearest_centre() {
        // Two swimmers side by side, boxes overlapping; the click is in both.
        let tracks = [
            track(1, 100.0, 100.0, 40.0, 40.0),
            track(2, 120.0, 100.0, 40.0, 40.0),
        ];
        let mut s = Selection::new(0.0);
        // x = 135 px: inside both; centre of 1 at 120, of 2 at 140.
        let o = s.command(&point(0.135, 0.24), &tracks, Some(SIZE));
        assert_eq!(s.selected().map(|s| s.track_id), Some(2), "{o:?}");
    }

    #[test]
    fn a_near_miss_within_the_radius_selects_the_nearest_box() {
        let tracks = [track(7, 100.0, 100.0, 10.0, 10.0)];
        // 20 px right of the box edge; radius 0.03 * 1000 = 30 px.
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        assert!(matches!(
            s.command(&point(0.13, 0.21), &tracks, Some(SIZE)),
            Outcome::Selected { track_id: 7, .. }
        ));
        // The command's own radius overrides the default: 0.01 * 1000 = 10 px is too small.
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        let o = s.command(
            &Request::Point {
                x: 0.13,
                y: 0.21,
                radius: Some(0.01),
            },
            &tracks,
            Some(SIZE),
        );
        assert_eq!(o, Outcome::Refused(Refusal::NothingAtPoint));
        assert_eq!(o.result(), CommandResult::Failed);
    }

    #[test]
    fn empty_sea_is_refused_and_keeps_the_previous_selection() {
        let tracks = [track(5, 100.0, 100.0, 10.0, 10.0)];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        s.command(&point(0.105, 0.21), &tracks, Some(SIZE));
        let o = s.command(&point(0.9, 0.9), &tracks, Some(SIZE));
        assert_eq!(o, Outcome::Refused(Refusal::NothingAtPoint));
        assert_eq!(s.selected().map(|s| s.track_id), Some(5));
        assert_eq!(
            s.command(&point(0.5, 0.5), &[], Some(SIZE)).result(),
            CommandResult::Failed
        );
        assert_eq!(
            s.command(&point(0.5, 0.5), &tracks, None),
            Outcome::Refused(Refusal::NoFrame)
        );
    }

    #[test]
    fn out_of_range_parameters_are_denied() {
        let tracks = [track(5, 100.0, 100.0, 10.0, 10.0)];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        for r in [
            point(1.5, 0.5),
            point(f64::NAN, 0.5),
            Request::Rectangle {
                x0: 0.1,
                y0: 0.1,
                x1: 0.1,
                y1: 0.5,
            },
            Request::Rectangle {
                x0: -0.1,
                y0: 0.1,
                x1: 0.3,
                y1: 0.5,
            },
        ] {
            let o = s.command(&r, &tracks, Some(SIZE));
            assert_eq!(o, Outcome::Refused(Refusal::InvalidArea), "{r:?}");
            assert_eq!(o.result(), CommandResult::Denied);
        }
        assert_eq!(s.selected(), None);
    }

    #[test]
    fn a_rectangle_picks_the_best_iou() {
        // A big boat box and a small swimmer; the rectangle is drawn tightly round the swimmer
        // but also grazes the boat.
        let tracks = [
            track(1, 100.0, 100.0, 200.0, 100.0),
            track(2, 310.0, 120.0, 20.0, 20.0),
        ];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        let o = s.command(
            &Request::Rectangle {
                x0: 0.295,
                y0: 0.23,
                x1: 0.335,
                y1: 0.29,
            },
            &tracks,
            Some(SIZE),
        );
        assert_eq!(
            o,
            Outcome::Selected {
                track_id: 2,
                mode: Mode::Rectangle
            }
        );
        // Corners in the other order mean the same rectangle.
        let mut s2 = Selection::new(DEFAULT_POINT_RADIUS);
        s2.command(
            &Request::Rectangle {
                x0: 0.335,
                y0: 0.29,
                x1: 0.295,
                y1: 0.23,
            },
            &tracks,
            Some(SIZE),
        );
        assert_eq!(s2.selected(), s.selected());
        let o = s.command(
            &Request::Rectangle {
                x0: 0.8,
                y0: 0.8,
                x1: 0.9,
                y1: 0.9,
            },
            &tracks,
            Some(SIZE),
        );
        assert_eq!(o, Outcome::Refused(Refusal::NothingInRectangle));
    }

    #[test]
    fn stop_ends_the_selection_and_is_accepted_when_idle() {
        let tracks = [track(5, 100.0, 100.0, 10.0, 10.0)];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        s.command(&point(0.105, 0.21), &tracks, Some(SIZE));
        let o = s.command(&Request::Stop, &tracks, Some(SIZE));
        assert_eq!(o, Outcome::Stopped { track_id: Some(5) });
        assert_eq!(s.selected(), None);
        let o = s.command(&Request::Stop, &[], None);
        assert_eq!(o, Outcome::Stopped { track_id: None });
        assert_eq!(o.result(), CommandResult::Accepted);
    }

    /// Live while `live` holds the id, remembered while `memory` does, gone otherwise.
    fn presence<'a>(live: &'a [u64], memory: &'a [u64]) -> impl Fn(u64) -> Presence + 'a {
        move |id| {
            if live.contains(&id) {
                Presence::Live
            } else if memory.contains(&id) {
                Presence::Remembered
            } else {
                Presence::Gone
            }
        }
    }

    #[test]
    fn the_selection_follows_a_reid_merge_and_ends_when_the_track_is_removed() {
        let tracks = [track(12, 100.0, 100.0, 10.0, 10.0)];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        s.command(&point(0.105, 0.21), &tracks, Some(SIZE));
        // Track 12 is recognised as old track 3: it is reported as 3 from now on.
        assert_eq!(s.follow(&[merge(12, 3)], presence(&[3], &[])), None);
        assert_eq!(
            s.selected(),
            Some(Selected {
                track_id: 3,
                mode: Mode::Point,
                lost: false,
            })
        );
        // A merge of some other track changes nothing.
        assert_eq!(s.follow(&[merge(20, 4)], presence(&[3], &[])), None);
        assert_eq!(s.selected().map(|s| s.track_id), Some(3));
        // Track 3 expires, and ReID does not remember it.
        assert_eq!(
            s.follow(&[], presence(&[], &[])),
            Some(Change::Ended { track_id: 3 })
        );
        assert_eq!(s.selected(), None);
        assert_eq!(s.follow(&[], presence(&[], &[])), None);
    }

    #[test]
    fn a_lost_selection_waits_for_reid_and_is_restored_under_its_id() {
        let tracks = [track(5, 100.0, 100.0, 10.0, 10.0)];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        s.command(&point(0.105, 0.21), &tracks, Some(SIZE));
        // The tracker's lost buffer gives track 5 up; its ReID memory keeps it.
        assert_eq!(
            s.follow(&[], presence(&[], &[5])),
            Some(Change::Lost { track_id: 5 })
        );
        assert_eq!(
            s.selected(),
            Some(Selected {
                track_id: 5,
                mode: Mode::Point,
                lost: true,
            })
        );
        // Lost it stays, frame after frame, whatever else is merged.
        assert_eq!(s.follow(&[merge(8, 2)], presence(&[2, 9], &[5])), None);
        assert_eq!(s.selected().map(|s| (s.track_id, s.lost)), Some((5, true)));
        // Track 9 is re-identified as 5: the selection is back on 5.
        assert_eq!(
            s.follow(&[merge(9, 5)], presence(&[2, 5], &[])),
            Some(Change::Restored { track_id: 5 })
        );
        assert_eq!(
            s.selected(),
            Some(Selected {
                track_id: 5,
                mode: Mode::Point,
                lost: false,
            })
        );
        // Lost again; this time the memory gives up on it: the selection ends.
        assert_eq!(
            s.follow(&[], presence(&[2], &[5])),
            Some(Change::Lost { track_id: 5 })
        );
        assert_eq!(
            s.follow(&[], presence(&[2], &[])),
            Some(Change::Ended { track_id: 5 })
        );
        assert_eq!(s.selected(), None);
    }

    #[test]
    fn a_new_selection_replaces_a_lost_one() {
        let tracks = [track(5, 100.0, 100.0, 10.0, 10.0)];
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        s.command(&point(0.105, 0.21), &tracks, Some(SIZE));
        s.follow(&[], presence(&[], &[5]));
        let other = [track(6, 500.0, 250.0, 20.0, 10.0)];
        s.command(&point(0.51, 0.51), &other, Some(SIZE));
        assert_eq!(s.selected().map(|s| (s.track_id, s.lost)), Some((6, false)));
        assert_eq!(s.follow(&[], presence(&[6], &[5])), None);
    }

    /// A swimmer at a fixed spot on the sea, seen at 20 frames per second, hidden for
    /// `hidden` frames (longer than the tracker's lost buffer), then seen again.
    fn swimmer_frame(i: u64, visible: bool) -> FrameInput {
        FrameInput {
            frame_index: i,
            time_s: i as f64 / 20.0,
            image_size_px: (1000, 500),
            detections: visible
                .then(|| Detection {
                    bbox: BBox::from_center(300.0, 200.0, 12.0, 12.0),
                    score: 0.9,
                    class_id: 1,
                    world: Some(WorldObservation {
                        pos_ne_m: Vector2::new(20.0, 5.0),
                        cov_ne_m2: Matrix2::identity() * 0.25,
                    }),
                    appearance: None,
                })
                .into_iter()
                .collect(),
            image_motion: None,
        }
    }

    #[test]
    fn a_selected_swimmer_lost_past_the_buffer_is_restored_by_long_term_reid() {
        let params = TrackerParams::default();
        let buffer = params.baseline.track_buffer_frames;
        let mut tracker = Tracker::new(params).unwrap();
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        let mut frame = 0;
        let mut step = |tracker: &mut Tracker, s: &mut Selection, visible: bool| {
            frame += 1;
            let out = tracker.step(&swimmer_frame(frame, visible)).unwrap();
            let change = s.follow(&out.merges, |id| Presence::of(tracker, id));
            (out, change)
        };
        let mut candidates = Vec::new();
        for _ in 0..30 {
            let (out, change) = step(&mut tracker, &mut s, true);
            assert_eq!(change, None);
            candidates = out
                .tracks
                .iter()
                .map(|t| Candidate {
                    id: t.id,
                    bbox: t.bbox,
                })
                .collect();
        }
        let Outcome::Selected { track_id, .. } =
            s.command(&point(0.3, 0.4), &candidates, Some(SIZE))
        else {
            panic!("nothing selected in {candidates:?}");
        };
        // Hidden for twice the lost buffer: lost, not ended.
        let mut changes = Vec::new();
        for _ in 0..2 * buffer {
            changes.extend(step(&mut tracker, &mut s, false).1);
        }
        assert_eq!(changes, vec![Change::Lost { track_id }]);
        assert_eq!(
            s.selected().map(|s| (s.track_id, s.lost)),
            Some((track_id, true))
        );
        // Seen again: a new track, re-identified as the old one, brings the id back.
        let mut merged = false;
        for _ in 0..30 {
            let (out, change) = step(&mut tracker, &mut s, true);
            merged |= out.merges.iter().any(|m| m.merged_into_id == track_id);
            changes.extend(change);
        }
        assert!(merged, "no ReID merge into {track_id}");
        assert_eq!(
            changes,
            vec![Change::Lost { track_id }, Change::Restored { track_id }]
        );
        assert_eq!(
            s.selected().map(|s| (s.track_id, s.lost)),
            Some((track_id, false))
        );
    }

    #[test]
    fn a_selection_ends_when_the_reid_memory_gives_up_on_its_track() {
        let mut params = TrackerParams::default();
        // Lost buffer 100 frames (5 s), memory 8 s.
        params.reid.memory_max_s = 8.0;
        let mut tracker = Tracker::new(params).unwrap();
        let mut s = Selection::new(DEFAULT_POINT_RADIUS);
        let mut candidates = Vec::new();
        for i in 1..=30 {
            let out = tracker.step(&swimmer_frame(i, true)).unwrap();
            candidates = out
                .tracks
                .iter()
                .map(|t| Candidate {
                    id: t.id,
                    bbox: t.bbox,
                })
                .collect();
        }
        s.command(&point(0.3, 0.4), &candidates, Some(SIZE));
        let track_id = s.selected().map(|s| s.track_id).unwrap();
        let mut changes = Vec::new();
        for i in 31..=330 {
            let out = tracker.step(&swimmer_frame(i, false)).unwrap();
            changes.extend(
                s.follow(&out.merges, |id| Presence::of(&tracker, id))
                    .map(|c| (i, c)),
            );
        }
        // Lost after the buffer (last seen at frame 30), ended 8 s after it was last seen.
        assert_eq!(
            changes,
            vec![
                (131, Change::Lost { track_id }),
                (191, Change::Ended { track_id }),
            ]
        );
        assert_eq!(s.selected(), None);
    }

    fn arb_tracks() -> impl Strategy<Value = Vec<Candidate>> {
        prop::collection::vec(
            (0.0..990.0f64, 0.0..490.0f64, 1.0..200.0f64, 1.0..200.0f64),
            1..12,
        )
        .prop_map(|boxes| {
            boxes
                .into_iter()
                .enumerate()
                .map(|(i, (x, y, w, h))| track(i as u64 + 1, x, y, w, h))
                .collect()
        })
    }

    proptest! {
        /// Clicking the centre of any track (inside the image) selects a track whose box holds
        /// the click, and the choice does not depend on the order the tracks come in.
        #[test]
        fn clicking_a_track_centre_selects_a_box_under_the_click(
            tracks in arb_tracks(),
            pick in any::<prop::sample::Index>(),
            radius in 0.0..0.1f64,
        ) {
            let t = tracks[pick.index(tracks.len())];
            let (cx, cy) = t.bbox.center();
            let (x, y) = ((cx / 1000.0).min(1.0), (cy / 500.0).min(1.0));
            let mut s = Selection::new(radius);
            let o = s.command(&point(x, y), &tracks, Some(SIZE));
            let Outcome::Selected { track_id, .. } = o else {
                return Err(TestCaseError::fail(format!("{o:?}")));
            };
            let chosen = tracks.iter().find(|c| c.id == track_id).unwrap().bbox;
            let (px, py) = (x * 1000.0, y * 500.0);
            prop_assert!(chosen.x <= px && px <= chosen.x + chosen.w);
            prop_assert!(chosen.y <= py && py <= chosen.y + chosen.h);
            let mut reversed = tracks.clone();
            reversed.reverse();
            let mut s2 = Selection::new(radius);
            prop_assert_eq!(s2.command(&point(x, y), &reversed, Some(SIZE)), o);
        }

        /// A rectangle drawn exactly on a track's box selects that box (or one identical to it).
        #[test]
        fn a_rectangle_on_a_box_selects_that_box(
            boxes in prop::collection::vec(
                (0.0..800.0f64, 0.0..300.0f64, 1.0..200.0f64, 1.0..200.0f64),
                1..12,
            ),
            pick in any::<prop::sample::Index>(),
        ) {
            let tracks: Vec<Candidate> = boxes
                .iter()
                .enumerate()
                .map(|(i, &(x, y, w, h))| track(i as u64 + 1, x, y, w, h))
                .collect();
            let b = tracks[pick.index(tracks.len())].bbox;
            let r = Request::Rectangle {
                x0: b.x / 1000.0,
                y0: b.y / 500.0,
                x1: (b.x + b.w) / 1000.0,
                y1: (b.y + b.h) / 500.0,
            };
            let mut s = Selection::new(0.0);
            let o = s.command(&r, &tracks, Some(SIZE));
            let Outcome::Selected { track_id, mode } = o else {
                return Err(TestCaseError::fail(format!("{o:?}")));
            };
            prop_assert_eq!(mode, Mode::Rectangle);
            let chosen = tracks.iter().find(|c| c.id == track_id).unwrap().bbox;
            prop_assert!(chosen.iou(&b) > 1.0 - 1e-9, "{:?} for {:?}", chosen, b);
        }

        /// Whatever chain of merges happens, the selection ends up on the id the selected
        /// track carries after them.
        #[test]
        fn merges_are_followed_through_chains(
            chain in prop::collection::vec(1u64..50, 0..6),
            noise in prop::collection::vec((1u64..50, 1u64..50), 0..6),
        ) {
            let tracks = [track(100, 100.0, 100.0, 10.0, 10.0)];
            let mut s = Selection::new(DEFAULT_POINT_RADIUS);
            s.command(&point(0.105, 0.21), &tracks, Some(SIZE));
            let mut expected = 100;
            for (i, &into) in chain.iter().enumerate() {
                // Unrelated merges of other tracks (never of the selected id) in the same step.
                let mut merges: Vec<MergeEvent> = noise
                    .iter()
                    .filter(|(n, _)| *n != expected && *n != into)
                    .map(|&(n, m)| merge(n, m))
                    .collect();
                merges.insert(i % (merges.len() + 1), merge(expected, into));
                expected = into;
                prop_assert_eq!(s.follow(&merges, presence(&[expected], &[])), None);
                prop_assert_eq!(s.selected().map(|s| s.track_id), Some(expected));
            }
        }
    }
}
