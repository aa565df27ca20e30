//! Readers and writers for the file formats mgmot exchanges: IO adapters around the pure core.
//!
//! Every reader reports malformed input as an error naming the file and the line or JSON path.

pub mod coco;
pub mod error;
pub mod geopoints;
pub mod input;
pub mod mot;
pub mod seadronessee;

pub use error::FormatError;
