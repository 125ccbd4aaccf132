//! # vfxgraph-serve
//!
//! `vfxgraph serve GRAPH`: the studio in a browser. An HTTP server (axum on tokio) that holds
//! one graph, plans and runs it with the engine's own [`vfxgraph_engine::exec::plan`] and
//! [`vfxgraph_engine::exec::run`] (not a copy), and pushes every engine event to the page as
//! server-sent events. The page (embedded in the binary, no network needed) shows the graph
//! coloured by plan state, the frames of any image output, the book's point-cloud definer
//! (§8.3, `defpcl`) and the solve in 3-D.
//!
//! - [`studio`]: the served state (graph, overrides, plan, live run state) and the run thread.
//! - [`events`]: the engine [`Observer`](vfxgraph_engine::Observer) that publishes events.
//! - [`access`]: who may drive it (Host, origin and JSON checks; a token off loopback).
//! - [`api`]: the HTTP routes.
//! - [`graph_file`]: a param edit saved into the graph file (one value's text, comments kept).
//! - [`safety`]: which files may be served, request errors as 4xx.
//! - [`preview`]: artifact decoding for the viewers (images, layers, JSON artifacts); the
//!   only module that knows node artifact types.
//! - [`definer`]: the point-cloud definer's marks file: read, validate, write, triangulate.
//! - [`refine`]: sub-pixel corner refinement of a definer click.
//! - [`assets`]: the embedded front end.

pub mod access;
pub mod api;
pub mod assets;
pub mod definer;
pub mod events;
pub mod graph_file;
pub mod preview;
pub mod refine;
pub mod safety;
pub mod studio;

use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;

pub use access::Access;
pub use api::router;
pub use studio::Studio;

/// What `vfxgraph serve` was asked for.
#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// The graph file.
    pub graph: PathBuf,
    /// The cache folder.
    pub cache_dir: PathBuf,
    /// Address to listen on (127.0.0.1 unless asked otherwise).
    pub bind: IpAddr,
    /// Port (0: any free port; the chosen one is printed).
    pub port: u16,
    /// Worker threads of runs (`None`: one per core).
    pub jobs: Option<usize>,
}

/// Serves the studio until the process ends. Prints `vfxgraph studio: http://ADDR/` on stdout
/// once listening (the port is the real one when 0 was asked; off loopback the URL carries the
/// token every request must show, [`access`]).
pub fn serve(opts: ServeOptions, registry: vfxgraph_engine::Registry) -> Result<(), String> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| format!("cannot start the server's runtime: {e}"))?;
    rt.block_on(async move {
        let addr = SocketAddr::new(opts.bind, opts.port);
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|e| format!("cannot listen on {addr}: {e}"))?;
        let local = listener.local_addr().map_err(|e| e.to_string())?;
        let studio = Arc::new(Studio::open(
            opts.graph.clone(),
            opts.cache_dir.clone(),
            Arc::new(registry),
            opts.jobs,
        ));
        {
            let s = studio.clone();
            tokio::task::spawn_blocking(move || s.refresh_plan())
                .await
                .map_err(|e| e.to_string())?;
        }
        let access = Access::for_address(local, None);
        match access.token() {
            None => println!("vfxgraph studio: http://{local}/"),
            Some(token) => {
                println!("vfxgraph studio: http://{local}/?token={token}");
                eprintln!(
                    "vfxgraph studio: listening off loopback ({local}): anyone on the network \
                     who has the URL above (its token) can read the graph's folder and run \
                     the graph; keep it private"
                );
            }
        }
        use std::io::Write;
        let _ = std::io::stdout().flush();
        axum::serve(listener, router(studio, access))
            .await
            .map_err(|e| format!("server stopped: {e}"))
    })
}
