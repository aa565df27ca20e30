//! The ground picture: the tracks of several drones fused into one id per object.
//!
//! Each drone's tracker already keeps one id per object over its own flight (short-term and
//! long-term ReID). What it cannot know is that the swimmer its track 12 follows is the one
//! another drone's track 7 follows. The fuser takes every drone's track reports (MGMOT_TRACK,
//! or the radio digest's positions where that is all that reaches the ground) and keeps one
//! *fused* track per object, with provenance: which drone's which track.
//!
//! - **Time-aligned:** reports carry a time on one clock for all drones
//!   ([`ClockAlign`] maps each autopilot's boot clock onto it); every state is predicted to
//!   the fuser's time before anything is compared.
//! - **Covariance-gated and class-aware:** a drone's track joins a fused track of its class
//!   when the squared Mahalanobis distance of the two positions (the sum of both covariances,
//!   grown by prediction) is inside a chi-square gate and they are within a distance cap.
//!   A fused track never takes two tracks of one drone that are alive together: the drone's
//!   own tracker has already said they are two objects.
//! - **Drift:** a fused track nobody sees any more is carried forward with the sea drift of
//!   its class, estimated from the tracks themselves exactly as the onboard tracker does it
//!   ([`SeaDrift`](crate::track::SeaDrift)), so a drone coming back minutes later finds it
//!   where the current took it.
//! - **Estimate:** the information-weighted mean of the live members, each predicted to now
//!   (independent drones: independent errors).
//! - **ReID from the drones:** a drone's merge (`merged_from_id`) merges the fused tracks of
//!   the two ids; two fused tracks of disjoint drones that stay inside the gate for
//!   `merge_after_s` are merged too (the lower id survives). Every retired fused id is
//!   reported once ([`Fuser::take_retired`]) so the outputs can end it.
//! - **A drone's ReID is checked, not just followed:** a drone track that comes back after a
//!   gap far from its fused track (or inside several fused tracks' gates) is held for
//!   `reacquire_hold_s`, moving nothing, and leaves as soon as another drone's live track or
//!   a better-fitting fused track says it is another object. A drone's new track may take the
//!   place of its drone's other track in a young fused track that it fits better
//!   (`rematch_within_s`), undoing a first pairing of two neighbours the wrong way round.
//!
//! Pure and synchronous: the caller passes every time; no IO.

mod clock;
mod fuser;
mod score;

pub use clock::ClockAlign;
pub use fuser::{
    FuseParams, FusedMember, FusedTrack, FusedTrackState, Fuser, MemberKey, Report, Retired,
};
pub use score::{match_sample, score_picture, FusedScore, PictureSample, ScoreParams, TruthObject};
