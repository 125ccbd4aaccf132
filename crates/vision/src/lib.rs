//! vfxgraph-vision
