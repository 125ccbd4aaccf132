//! vfxgraph-vision

pub mod bundle;
