//! The integration tests of `mgmot-sim`, in one test binary as ripgrep does: one module per
//! area, all on one harness, [`common`]. Run one area with a module path filter, e.g.
//! `cargo test -p mgmot-sim --release --test main -- stream::`.

mod common;

mod cli;
mod follow;
mod geometry;
mod pymavlink;
mod serial;
mod stream;
