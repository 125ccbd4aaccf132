//! Cache and scheduler behaviour: partial reruns, early cutoff, file inputs, writers,
//! failures, concurrency and determinism.

mod common;

use std::fs;
use std::time::{Duration, SystemTime};

use common::{ran_cached, registry, Scratch};
use vfxgraph_engine::{exec, PlanStatus, RunOptions, Status, Target};

const CHAIN: &str = "version: 1
nodes:
  a: {type: num, params: {value: 1.2}}
  b: {type: num, params: {value: 10}}
  r: {type: round, inputs: {a: a.out}}
  s: {type: add, inputs: {a: r.out, b: b.out}, params: {offset: OFFSET}}
  t: {type: add, inputs: {a: s.out}}
  u: {type: add, inputs: {a: b.out}}
";

fn chain(a: &str, offset: &str) -> String {
    CHAIN.replace("1.2", a).replace("OFFSET", offset)
}

#[test]
fn second_run_is_all_cached() {
    let s = Scratch::new();
    let r1 = s.run(&chain("1.2", "0"));
    assert!(r1.nodes.iter().all(|n| n.status == Status::Ran), "{r1:?}");
    let r2 = s.run(&chain("1.2", "0"));
    assert!(
        r2.nodes.iter().all(|n| n.status == Status::Cached),
        "{r2:?}"
    );
    let p = exec::plan(&s.graph(&chain("1.2", "0")), &s.opts()).unwrap();
    assert!(p.nodes.iter().all(|n| n.status == PlanStatus::Cached));
}

#[test]
fn one_param_reruns_exactly_its_node_and_dependants() {
    let s = Scratch::new();
    s.run(&chain("1.2", "0"));
    let g = s.graph(&chain("1.2", "5"));
    let p = exec::plan(&g, &s.opts()).unwrap();
    let status = |id: &str| p.nodes.iter().find(|n| n.id == id).unwrap().clone();
    assert_eq!(status("s").status, PlanStatus::Run);
    assert!(
        status("s")
            .reason
            .contains("param `offset` changed (0 → 5)"),
        "{}",
        status("s").reason
    );
    assert_eq!(status("t").status, PlanStatus::Blocked);
    for id in ["a", "b", "r", "u"] {
        assert_eq!(status(id).status, PlanStatus::Cached, "{id}");
    }
    let r = s.run(&chain("1.2", "5"));
    let ran: Vec<_> = r
        .nodes
        .iter()
        .filter(|n| n.status == Status::Ran)
        .map(|n| n.id.as_str())
        .collect();
    assert_eq!(ran, vec!["s", "t"]);
    let cosmetic = chain("1.2", "5").replace("value: 10}", "value: 10, label: hello}");
    let r = s.run(&cosmetic);
    assert!(
        r.nodes.iter().all(|n| n.status == Status::Cached),
        "a cosmetic param reruns nothing"
    );
}

#[test]
fn identical_upstream_bytes_rerun_nothing_below() {
    let s = Scratch::new();
    s.run(&chain("1.2", "0"));
    // a changes 1.2 → 1.3: `a` reruns, `round` reruns and yields 1.0 again: early cutoff.
    let r = s.run(&chain("1.3", "0"));
    assert_eq!(ran_cached(&r, "a"), (1, 0));
    assert_eq!(ran_cached(&r, "r"), (1, 0));
    for id in ["s", "t", "u", "b"] {
        assert_eq!(ran_cached(&r, id), (0, 1), "{id}");
    }
}

const FILES: &str = "version: 1
frames: 1-4
nodes:
  read: {type: read_num, params: {path: \"in/####.txt\"}}
  twice: {type: add, inputs: {a: read.out, b: read.out}}
  total: {type: sum, inputs: {items: twice.out}}
";

fn write_inputs(s: &Scratch) {
    for f in 1..=4 {
        s.write(&format!("in/{f:04}.txt"), &format!("{f}\n"));
    }
}

fn set_mtime(p: &std::path::Path, t: SystemTime) {
    fs::File::options()
        .append(true)
        .open(p)
        .unwrap()
        .set_modified(t)
        .unwrap();
}

#[test]
fn one_frame_file_change_reruns_one_frame() {
    let s = Scratch::new();
    write_inputs(&s);
    let r = s.run(FILES);
    assert_eq!(ran_cached(&r, "twice"), (4, 0));
    // Change frame 3's file: only frame 3 of the per-frame consumer reruns.
    s.write("in/0003.txt", "30\n");
    let r = s.run(FILES);
    assert_eq!(ran_cached(&r, "read"), (1, 3));
    assert_eq!(ran_cached(&r, "twice"), (1, 3));
    let again = r
        .nodes
        .iter()
        .find(|n| n.id == "twice" && n.status == Status::Ran)
        .unwrap();
    assert_eq!(again.frame, Some(3));
    assert!(
        again.reason.contains("input `a` changed"),
        "{}",
        again.reason
    );
    let read3 = r
        .nodes
        .iter()
        .find(|n| n.id == "read" && n.status == Status::Ran)
        .unwrap();
    assert!(
        read3.reason.contains("0003.txt changed"),
        "{}",
        read3.reason
    );
    assert_eq!(ran_cached(&r, "total"), (1, 0));
}

#[test]
fn touching_reruns_nothing_content_change_reruns_readers() {
    let s = Scratch::new();
    write_inputs(&s);
    // Old mtimes, so the memo holds them.
    let old = SystemTime::now() - Duration::from_secs(3600);
    for f in 1..=4 {
        set_mtime(&s.path(&format!("in/{f:04}.txt")), old);
    }
    s.run(FILES);
    // Touch all files: new mtime, same content.
    for f in 1..=4 {
        set_mtime(&s.path(&format!("in/{f:04}.txt")), SystemTime::now());
    }
    let r = s.run(FILES);
    assert!(r.nodes.iter().all(|n| n.status == Status::Cached), "{r:?}");
    // Same size, same mtime as before, different content: a racy edit the memo must not hide
    // (files touched within two seconds are re-hashed).
    s.write("in/0002.txt", "7\n");
    let r = s.run(FILES);
    assert_eq!(ran_cached(&r, "read"), (1, 3));
}

const LISTED: &str = "version: 1
nodes:
  listed: {type: sum_listed, params: {list: in/list.txt}}
  paths: {type: sum_paths, params: {paths: [in/a.txt, in/b.txt]}}
  l2: {type: add, inputs: {a: listed.out}, params: {offset: 100}}
  p2: {type: add, inputs: {a: paths.out}}
";

#[test]
fn files_named_inside_a_list_or_a_path_list_are_hashed() {
    let s = Scratch::new();
    s.write("in/list.txt", "a.txt\nb.txt\n");
    s.write("in/a.txt", "1\n");
    s.write("in/b.txt", "2\n");
    let r = s.run(LISTED);
    assert!(r.nodes.iter().all(|n| n.status == Status::Ran), "{r:?}");
    let r = s.run(LISTED);
    assert!(r.nodes.iter().all(|n| n.status == Status::Cached), "{r:?}");
    // Editing one listed file (the list file itself unchanged) reruns both readers and their
    // dependants; plan says why.
    s.write("in/b.txt", "5\n");
    let p = exec::plan(&s.graph(LISTED), &s.opts()).unwrap();
    let listed = p.nodes.iter().find(|n| n.id == "listed").unwrap();
    assert_eq!(listed.status, PlanStatus::Run);
    assert!(listed.reason.contains("b.txt changed"), "{}", listed.reason);
    let paths = p.nodes.iter().find(|n| n.id == "paths").unwrap();
    assert!(paths.reason.contains("b.txt changed"), "{}", paths.reason);
    let r = s.run(LISTED);
    for id in ["listed", "paths", "l2", "p2"] {
        assert_eq!(ran_cached(&r, id), (1, 0), "{id}: {r:?}");
    }
    let r = s.run(LISTED);
    assert!(r.nodes.iter().all(|n| n.status == Status::Cached), "{r:?}");
    // A listed file that disappears: the cached entry is invalid, the rerun fails naming it.
    fs::remove_file(s.path("in/a.txt")).unwrap();
    let r = s.run(LISTED);
    let listed = r.nodes.iter().find(|n| n.id == "listed").unwrap();
    assert_eq!(listed.status, Status::Failed);
    assert!(listed.reason.contains("a.txt"), "{}", listed.reason);
    let paths = r.nodes.iter().find(|n| n.id == "paths").unwrap();
    assert_eq!(paths.status, Status::Failed);
    assert!(paths.reason.contains("a.txt"), "{}", paths.reason);
}

#[test]
fn missing_input_file_fails_that_frame_only() {
    let s = Scratch::new();
    write_inputs(&s);
    fs::remove_file(s.path("in/0002.txt")).unwrap();
    let r = s.run(FILES);
    let read2 = r
        .nodes
        .iter()
        .find(|n| n.id == "read" && n.frame == Some(2))
        .unwrap();
    assert_eq!(read2.status, Status::Failed);
    assert!(read2.reason.contains("0002.txt"), "{}", read2.reason);
    assert_eq!(ran_cached(&r, "twice"), (3, 0));
    assert_eq!(r.count("twice", Status::Skipped), 1);
    assert_eq!(r.count("total", Status::Skipped), 1);
    assert!(r.failed());
    // Restore it: only the missing parts run.
    s.write("in/0002.txt", "2\n");
    let r = s.run(FILES);
    assert_eq!(ran_cached(&r, "read"), (1, 3));
    assert_eq!(ran_cached(&r, "twice"), (1, 3));
    assert!(!r.failed());
}

#[test]
fn failure_skips_dependants_and_keeps_independent_branches() {
    let s = Scratch::new();
    let g = "version: 1
nodes:
  a: {type: num, params: {value: 1}}
  bad: {type: fail, inputs: {a: a.out}}
  after: {type: add, inputs: {a: bad.out}}
  fine: {type: add, inputs: {a: a.out}}
";
    let r = s.run(g);
    assert_eq!(r.count("bad", Status::Failed), 1);
    assert_eq!(r.count("after", Status::Skipped), 1);
    assert!(r
        .nodes
        .iter()
        .find(|n| n.id == "after")
        .unwrap()
        .reason
        .contains("`bad`"));
    assert_eq!(r.count("fine", Status::Ran), 1);
    let r = s.run(g);
    assert_eq!(
        r.count("fine", Status::Cached),
        1,
        "independent branch was cached"
    );
    assert_eq!(r.count("bad", Status::Failed), 1, "failures are not cached");
}

#[test]
fn writer_reruns_when_its_file_is_gone_or_changed() {
    let s = Scratch::new();
    let g = "version: 1
nodes:
  a: {type: num, params: {value: 4}}
  w: {type: write_num, inputs: {a: a.out}, params: {path: out/v.txt}}
";
    let r = s.run(g);
    assert_eq!(r.count("w", Status::Ran), 1);
    assert_eq!(fs::read_to_string(s.path("out/v.txt")).unwrap(), "4\n");
    assert_eq!(s.run(g).count("w", Status::Cached), 1);
    fs::remove_file(s.path("out/v.txt")).unwrap();
    let p = exec::plan(&s.graph(g), &s.opts()).unwrap();
    let w = p.nodes.iter().find(|n| n.id == "w").unwrap();
    assert_eq!(w.status, PlanStatus::Run);
    assert!(w.reason.contains("missing"), "{}", w.reason);
    assert_eq!(s.run(g).count("w", Status::Ran), 1);
    assert_eq!(fs::read_to_string(s.path("out/v.txt")).unwrap(), "4\n");
    s.write("out/v.txt", "edited\n");
    assert_eq!(s.run(g).count("w", Status::Ran), 1);
    assert_eq!(fs::read_to_string(s.path("out/v.txt")).unwrap(), "4\n");
}

/// A file written through `Context::write_file` beside the path param's is an output too: the
/// entry is stale when it is deleted or edited, and the run writes it again.
#[test]
fn files_written_through_the_context_are_outputs() {
    let s = Scratch::new();
    let w = "w: {type: write_num_note, inputs: {a: a.out}, params: {path: out/v.txt}}";
    let g = &format!("version: 1\nnodes:\n  a: {{type: num, params: {{value: 4}}}}\n  {w}\n");
    let note = s.path("out/v.note");
    assert_eq!(s.run(g).count("w", Status::Ran), 1);
    for edit in [None, Some("edited\n")] {
        assert_eq!(s.run(g).count("w", Status::Cached), 1);
        match edit {
            None => fs::remove_file(&note).unwrap(),
            Some(text) => fs::write(&note, text).unwrap(),
        }
        let plan = exec::plan(&s.graph(g), &s.opts()).unwrap();
        let w = plan.nodes.iter().find(|n| n.id == "w").unwrap();
        let why = &w.reason;
        assert!(
            w.status == PlanStatus::Run && why.contains("v.note"),
            "{why}"
        );
        assert_eq!(s.run(g).count("w", Status::Ran), 1);
        assert_eq!(fs::read_to_string(&note).unwrap(), "a note\n");
    }
}

#[test]
fn corrupt_or_lost_objects_are_recomputed() {
    let s = Scratch::new();
    let g = chain("1.2", "0");
    s.run(&g);
    // Delete every object: plan says rerun; values that are still needed are recomputed.
    let objects = s.path(".vfxgraph/objects");
    fs::remove_dir_all(&objects).unwrap();
    fs::create_dir_all(&objects).unwrap();
    let p = exec::plan(&s.graph(&g), &s.opts()).unwrap();
    assert!(p.nodes.iter().any(|n| n.reason.contains("missing")));
    let r = s.run(&g);
    assert!(!r.failed());
    // Now flip a byte in every object: reads fail verification, results recompute correctly.
    let mut n = 0;
    for shard in fs::read_dir(&objects).unwrap() {
        for f in fs::read_dir(shard.unwrap().path()).unwrap() {
            let p = f.unwrap().path();
            let mut b = fs::read(&p).unwrap();
            let last = b.len() - 1;
            b[last] ^= 0x55;
            fs::write(&p, b).unwrap();
            n += 1;
        }
    }
    assert!(n > 0);
    // Force `t` to run so it must load its (corrupt) input `s`.
    let mut o = s.opts();
    o.force = vec!["t".into()];
    let r = exec::run(&s.graph(&g), &registry(), &o, &exec::Quiet).unwrap();
    assert!(!r.failed(), "{r:?}");
    assert_eq!(r.count("t", Status::Ran), 1);
}

#[test]
fn independent_nodes_run_concurrently() {
    let s = Scratch::new();
    let g = "version: 1
nodes:
  one: {type: rendezvous, params: {name: one}}
  two: {type: rendezvous, params: {name: two}}
";
    let mut o = s.opts();
    o.cache_dir = None;
    let r = exec::run(&s.graph(g), &registry(), &o, &exec::Quiet).unwrap();
    assert!(!r.failed(), "{r:?}");
    assert_eq!(r.count("one", Status::Ran) + r.count("two", Status::Ran), 2);
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let g = "version: 1
frames: 0..=63
seed: 42
nodes:
  r: {type: ramp, params: {scale: 0.5}}
  x: {type: rand, per_frame: true}
  y: {type: add, inputs: {a: r.out, b: x.out}}
  total: {type: sum, inputs: {items: y.out}}
";
    let mut digests = Vec::new();
    for jobs in [1, 8] {
        let s = Scratch::new();
        let mut o = s.opts();
        o.jobs = Some(jobs);
        exec::run(&s.graph(g), &registry(), &o, &exec::Quiet).unwrap();
        // The action entries (keys → output digests) must be identical.
        let mut entries: Vec<(String, Vec<String>)> =
            vfxgraph_engine::store::Store::open(&s.path(".vfxgraph"))
                .unwrap()
                .list()
                .into_iter()
                .map(|e| {
                    (
                        e.key,
                        e.entry.outputs.into_iter().map(|o| o.digest).collect(),
                    )
                })
                .collect();
        entries.sort();
        assert_eq!(entries.len(), 64 * 3 + 1);
        digests.push(entries);
    }
    assert_eq!(digests[0], digests[1]);
}

#[test]
fn seeded_nodes_differ_by_seed_frame_and_id() {
    let s = Scratch::new();
    let g = "version: 1\nframes: 0..=1\nseed: SEED\nnodes:\n  x: {type: rand, per_frame: true}\n  y: {type: rand, per_frame: true}\n";
    let r = s.run(&g.replace("SEED", "1"));
    assert_eq!(ran_cached(&r, "x"), (2, 0));
    let r = s.run(&g.replace("SEED", "1"));
    assert_eq!(ran_cached(&r, "x"), (0, 2));
    let r = s.run(&g.replace("SEED", "2"));
    assert_eq!(ran_cached(&r, "x"), (2, 0));
    assert!(r.nodes[0].reason.contains("seed"), "{}", r.nodes[0].reason);
    let a = exec::seed_for(2, "x", Some(0));
    assert_ne!(a, exec::seed_for(2, "x", Some(1)));
    assert_ne!(a, exec::seed_for(2, "y", Some(0)));
    assert_ne!(a, exec::seed_for(3, "x", Some(0)));
}

#[test]
fn no_cache_runs_everything_and_writes_nothing() {
    let s = Scratch::new();
    let g = s.graph(&chain("1.2", "0"));
    let o = RunOptions {
        jobs: Some(2),
        cache_dir: None,
        force: vec![],
        cancel: None,
        only: None,
    };
    let r = exec::run(&g, &registry(), &o, &exec::Quiet).unwrap();
    assert!(r.nodes.iter().all(|n| n.status == Status::Ran));
    assert!(!s.path(".vfxgraph").exists());
}

#[test]
fn force_reruns_one_node() {
    let s = Scratch::new();
    let g = chain("1.2", "0");
    s.run(&g);
    let mut o = s.opts();
    o.force = vec!["s".into()];
    let r = exec::run(&s.graph(&g), &registry(), &o, &exec::Quiet).unwrap();
    let ran: Vec<_> = r
        .nodes
        .iter()
        .filter(|n| n.status == Status::Ran)
        .map(|n| n.id.as_str())
        .collect();
    assert_eq!(ran, vec!["s"], "same output bytes: dependants stay cached");
    o.force = vec!["nope".into()];
    assert!(exec::run(&s.graph(&g), &registry(), &o, &exec::Quiet).is_err());
}

fn only(targets: &[(&str, Option<Vec<i64>>)]) -> Option<Vec<Target>> {
    Some(
        targets
            .iter()
            .map(|(n, f)| Target {
                node: n.to_string(),
                frames: f.clone(),
            })
            .collect(),
    )
}

/// `exec`'s selection: exactly the named instances run, their inputs come from the cache only
/// (a miss fails naming the upstream instance), the rest is not visited; the entries equal a
/// whole run's.
#[test]
fn selected_instances_run_alone_on_cached_inputs() {
    let s = Scratch::new();
    write_inputs(&s);
    let g = s.graph(FILES);
    let reg = registry();
    let mut o = s.opts();
    // Nothing cached: frame 2 of `twice` needs `read` frame 2, which is not run for it.
    o.only = only(&[("twice", Some(vec![2]))]);
    let r = exec::run(&g, &reg, &o, &exec::Quiet).unwrap();
    assert!(r.failed());
    let read2 = r.nodes.iter().find(|n| n.id == "read").unwrap();
    assert_eq!((read2.frame, read2.status), (Some(2), Status::Failed));
    assert!(
        read2.reason.contains("not in the cache"),
        "{}",
        read2.reason
    );
    let twice2 = r.nodes.iter().find(|n| n.id == "twice").unwrap();
    assert_eq!(twice2.status, Status::Skipped);
    assert!(
        twice2.reason.contains("`read` frame 2"),
        "{}",
        twice2.reason
    );
    assert_eq!(
        r.nodes.len(),
        2,
        "only the selection and its inputs are visited"
    );
    // Run `read` frames 1-4 alone, then `twice` in two chunks, then `total`.
    for sel in [
        only(&[("read", None)]),
        only(&[("twice", Some(vec![1, 2]))]),
        only(&[("twice", Some(vec![3, 4]))]),
        only(&[("total", None)]),
    ] {
        o.only = sel;
        let r = exec::run(&g, &reg, &o, &exec::Quiet).unwrap();
        assert!(!r.failed(), "{:?}", r.nodes);
        assert!(r
            .nodes
            .iter()
            .all(|n| n.status != Status::Ran
                || o.only.as_ref().unwrap().iter().any(|t| t.node == n.id)));
    }
    assert_eq!(ran_cached(&s.run(FILES), "total"), (0, 1));
    // The same entries as a whole run in a fresh cache.
    let whole = Scratch::new();
    write_inputs(&whole);
    whole.run(FILES);
    let keys = |dir: &std::path::Path| {
        let mut k: Vec<_> = vfxgraph_engine::store::Store::open(dir)
            .unwrap()
            .list()
            .into_iter()
            .map(|e| (e.key, e.entry.outputs))
            .collect();
        k.sort_by(|a, b| a.0.cmp(&b.0));
        k
    };
    assert_eq!(keys(&s.path(".vfxgraph")), keys(&whole.path(".vfxgraph")));
}

#[test]
fn bad_selections_are_errors() {
    let s = Scratch::new();
    write_inputs(&s);
    let g = s.graph(FILES);
    let mut o = s.opts();
    for (sel, msg) in [
        (only(&[("nope", None)]), "no node `nope`"),
        (
            only(&[("twice", Some(vec![9]))]),
            "frame 9 is not in the graph's frames",
        ),
        (only(&[("total", Some(vec![1]))]), "`total` runs once"),
    ] {
        o.only = sel;
        let e = exec::run(&g, &registry(), &o, &exec::Quiet).err().unwrap();
        assert!(e.to_string().contains(msg), "{e}");
    }
}

/// An uncached reader (`NodeSpec::uncached`): its action entries are stored, its objects are
/// not; it shows as cached on the next run, and a consumer that reruns gets its frames
/// recomputed — also where only selected instances may run (a farm task) — with the same
/// results and entries as a cached reader's.
#[test]
fn uncached_readers_store_entries_not_objects() {
    let uncached = FILES.replace("type: read_num,", "type: read_num_uncached,");
    // Values no consumer also produces (content addressing would share their objects).
    let write_inputs = |s: &Scratch| {
        for f in 1..=4 {
            s.write(&format!("in/{f:04}.txt"), &format!("{f}.1\n"));
        }
    };
    let s = Scratch::new();
    write_inputs(&s);
    let r = s.run(&uncached);
    assert_eq!(ran_cached(&r, "read"), (4, 0));
    let store = vfxgraph_engine::store::Store::open(&s.path(".vfxgraph")).unwrap();
    let entries = store.list();
    let reads: Vec<_> = entries
        .iter()
        .filter(|e| e.entry.node_id == "read")
        .collect();
    assert_eq!(reads.len(), 4);
    for e in &reads {
        let d = vfxgraph_engine::Digest::from_hex(&e.entry.outputs[0].digest).unwrap();
        assert!(
            !store.has_object(&d),
            "an uncached reader's object was stored"
        );
    }
    // Everything cached; the plan agrees.
    let r = s.run(&uncached);
    assert!(r.nodes.iter().all(|n| n.status == Status::Cached), "{r:?}");
    let p = exec::plan(&s.graph(&uncached), &s.opts()).unwrap();
    assert!(p.nodes.iter().all(|n| n.status == PlanStatus::Cached));
    // `twice` forced: it reads the four frames, recomputed, with the same result.
    let g = s.graph(&uncached);
    let mut o = s.opts();
    o.force = vec!["twice".into()];
    let r = exec::run(&g, &registry(), &o, &exec::Quiet).unwrap();
    assert!(!r.failed(), "{r:?}");
    assert_eq!(ran_cached(&r, "read"), (0, 4));
    assert_eq!(ran_cached(&r, "twice"), (4, 0));
    assert_eq!(ran_cached(&r, "total"), (0, 1), "same bytes: early cutoff");
    // A farm task: `twice` frame 3 alone, its input from the cache only.
    o.force = vec!["twice".into()];
    o.only = only(&[("twice", Some(vec![3]))]);
    let r = exec::run(&g, &registry(), &o, &exec::Quiet).unwrap();
    assert!(!r.failed(), "{r:?}");
    assert_eq!(r.count("twice", Status::Ran), 1);
    // The same output digests as with a cached reader, read's entries aside (an uncached
    // reader's outputs are named by its key).
    let cached = Scratch::new();
    write_inputs(&cached);
    cached.run(FILES);
    let outputs = |dir: &std::path::Path| {
        let mut k: Vec<_> = vfxgraph_engine::store::Store::open(dir)
            .unwrap()
            .list()
            .into_iter()
            .filter(|e| e.entry.node_id != "read")
            .map(|e| (e.entry.node_id, e.entry.frame, e.entry.outputs))
            .collect();
        k.sort_by(|a, b| (&a.0, a.1).cmp(&(&b.0, b.1)));
        k
    };
    assert_eq!(
        outputs(&s.path(".vfxgraph")),
        outputs(&cached.path(".vfxgraph"))
    );
    // A frame's file edited after the run: that frame reruns (and is recomputed, not loaded).
    s.write("in/0002.txt", "20\n");
    let r = s.run(&uncached);
    assert_eq!(ran_cached(&r, "read"), (1, 3));
    assert_eq!(ran_cached(&r, "twice"), (1, 3));
}

/// An uncached reader is not computed when the run resolves it: a streamed consumer computes
/// the frames it reads, when it reads them, and no others; a rerun computes nothing; an
/// edited frame reruns alone; a frame that does not parse fails the consumer with the reader's
/// name, frame and file.
#[test]
fn uncached_readers_are_computed_when_a_streamed_consumer_reads_them() {
    use std::sync::atomic::Ordering::SeqCst;
    let graph = "version: 1
frames: 1-4
nodes:
  read: {type: read_num_counted, params: {path: \"in/####.txt\"}}
  total: {type: sum_every_other, inputs: {items: read.out}}
";
    let counted = || common::COUNTED_READS.load(SeqCst);
    let s = Scratch::new();
    write_inputs(&s);
    let r = s.run(graph);
    assert!(!r.failed(), "{r:?}");
    assert_eq!(ran_cached(&r, "read"), (4, 0));
    assert_eq!(counted(), 2, "frames 1 and 3 read, 2 and 4 never computed");
    let total_is = |v: f64| {
        let store = vfxgraph_engine::store::Store::open(&s.path(".vfxgraph")).unwrap();
        let want = vfxgraph_engine::Value::new(v).digest().to_hex();
        store
            .list()
            .iter()
            .any(|e| e.entry.node_id == "total" && e.entry.outputs[0].digest == want)
    };
    assert!(total_is(1.0 + 3.0));
    let r = s.run(graph);
    assert!(r.nodes.iter().all(|n| n.status == Status::Cached), "{r:?}");
    assert_eq!(counted(), 2, "a rerun computes nothing");
    s.write("in/0003.txt", "30\n");
    let r = s.run(graph);
    assert_eq!(ran_cached(&r, "read"), (1, 3));
    assert_eq!(ran_cached(&r, "total"), (1, 0));
    assert_eq!(counted(), 4);
    assert!(total_is(1.0 + 30.0));
    s.write("in/0001.txt", "one\n");
    let r = s.run(graph);
    let failed = r.nodes.iter().find(|n| n.id == "total").unwrap();
    assert_eq!(failed.status, Status::Failed);
    assert!(
        failed.reason.contains("frame 1")
            && failed.reason.contains("`read`")
            && failed.reason.contains("0001.txt"),
        "{}",
        failed.reason
    );
}

/// Only input-less nodes may be uncached: a recompute must need nothing but the graph.
#[test]
#[should_panic(expected = "uncached but has inputs")]
fn an_uncached_node_with_inputs_is_refused() {
    let mut r = registry();
    r.register_node(common::Round(
        vfxgraph_engine::NodeSpec::new("round_uncached", "")
            .uncached()
            .input(vfxgraph_engine::PortSpec::one("a", "float", ""))
            .output(vfxgraph_engine::PortSpec::one("out", "float", "")),
    ));
}
