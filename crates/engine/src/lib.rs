//! vfxgraph-engine
