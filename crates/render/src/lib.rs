//! vfxgraph-render
pub mod dome;
