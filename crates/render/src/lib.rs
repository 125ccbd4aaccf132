//! vfxgraph-render
