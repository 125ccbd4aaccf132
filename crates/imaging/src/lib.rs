//! vfxgraph-imaging
