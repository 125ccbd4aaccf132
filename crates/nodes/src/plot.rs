//! The solve-error plot of a matchmove report, drawn by [`vfxgraph_imaging::draw::svg`].

pub use vfxgraph_imaging::draw::svg::solve_error_svg;
