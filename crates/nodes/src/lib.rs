//! vfxgraph-nodes
