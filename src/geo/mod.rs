//! Geometry (placeholder, being written).
