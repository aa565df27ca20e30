//! Readers and writers for tracking annotation files (IO edge of the crate).

pub mod mot;
