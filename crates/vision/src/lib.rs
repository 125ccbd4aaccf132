//! vfxgraph-vision
pub mod klt;
