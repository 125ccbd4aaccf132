use super::*;

/// A book-demo file's text; `None` when absent (a failure under CI=true).
fn data(name: &str) -> Option<String> {
    let p = vfxgraph_testdata::path(&format!("book-demo/{name}"))?;
    Some(std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
}

#[test]
fn reads_the_books_cornell_box() {
    let Some(text) = data("cornell.scn") else {
        return;
    };
    let s = parse_scn(&text).unwrap();
    assert_eq!(
        (
            s.camera.as_ref().unwrap().width,
            s.camera.as_ref().unwrap().height
        ),
        (640, 480)
    );
    assert!((s.camera.as_ref().unwrap().center() - Vec3::new(5.0, 20.0, 5.0)).length() < 1e-12);
    assert_eq!(s.objects.len(), 8);
    assert_eq!(s.lights.len(), 1);
    assert_eq!(s.lights[0].triangles.len(), 2);
    assert!((s.lights[0].radiance.r - 9.0 * PI).abs() < 1e-12);
    assert!(
        matches!(s.objects[0].material, Brdf::Mirror(m) if (m.reflectance.g - 0.9).abs() < 1e-12)
    );
    match s.objects[1].material {
        Brdf::BlinnPhong(b) => {
            assert_eq!(b.exponent, 10.0, "S3D default se");
            assert!((b.diffuse.b - 0.4 * 0.6).abs() < 1e-12 && (b.specular.r - 0.3).abs() < 1e-12);
        }
        other => panic!("{other:?}"),
    }
    match s.objects[3].material {
        Brdf::Lambert(l) => assert!((l.albedo.r - 0.36).abs() < 1e-12),
        other => panic!("{other:?}"),
    }
    assert!(s.dome.is_none() && s.background == Rgb::BLACK);
}

#[test]
fn reads_the_books_modeling_scene() {
    let Some(text) = data("modeling.scn") else {
        return;
    };
    let s = parse_scn(&text).unwrap();
    let dome = s.dome.as_ref().unwrap();
    assert_eq!(dome.image, "dome.pfm");
    assert!((dome.south.y - 0.821183).abs() < 1e-12);
    assert_eq!(
        (
            s.camera.as_ref().unwrap().width,
            s.camera.as_ref().unwrap().height
        ),
        (1280, 720)
    );
    let catchers: Vec<_> = s.catchers().collect();
    assert_eq!(catchers.len(), 1);
    assert_eq!(s.objects.len(), 3);
    assert_eq!(s.without_synthetic_objects().objects.len(), 1);
    // `kd = 1.0.` (the book's typo) reads as 1.0: albedo = d_col.
    match catchers[0].material {
        Brdf::Lambert(l) => assert!((l.albedo.r - 0.576563).abs() < 1e-12),
        other => panic!("{other:?}"),
    }
}

fn error_at(text: &str) -> (usize, usize, String) {
    let e = parse_scn(text).unwrap_err();
    (e.line, e.col, e.message)
}

#[test]
fn errors_point_at_line_and_column() {
    let (l, c, m) = error_at("scene{\n  object = primobj{ shape = sphere{ radius = -1 } }\n}");
    assert_eq!((l, c), (2, 46), "{m}");
    assert!(m.contains("radius"), "{m}");
    let (l, c, m) = error_at("scene{\n camera = view{ fvo = 3 }\n}");
    assert_eq!((l, c), (2, 17), "{m}");
    assert!(m.contains("unknown field `fvo`"), "{m}");
    let (l, c, m) =
        error_at("scene{\n  object = polyobj{ shape = trilist{ {{0,0,0},{1,0,0}} } }\n}");
    assert_eq!((l, c), (2, 38), "{m}");
    let (l, c, m) = error_at("scene{ object = primobj{ shape = sphere{} }");
    assert_eq!((l, c), (1, 6), "{m}");
    assert!(m.contains("never closed"), "{m}");
    let (l, c, _) = error_at("scene{ x = 1 @ }");
    assert_eq!((l, c), (1, 14));
    let (_, _, m) = error_at("scene{ camera = view{ from = {0,0,0}, at = {0,0,0} } }");
    assert!(m.contains("from = at"), "{m}");
    let (_, _, m) = error_at("scene{ camera = view{ imgw = 0 } }");
    assert!(m.contains("imgw"), "{m}");
    let (_, _, m) = error_at("scene{ dome = hdrdome{ hdrimg = \"a.pfm\" } }");
    assert!(m.contains("hdrscene"), "{m}");
    let (_, _, m) =
        error_at("scene{ object = primobj{ material = plastic{ kt = 1 }, shape = sphere{} } }");
    assert!(m.contains("kt"), "{m}");
    assert!(parse_scn("").is_err());
    assert!(parse_scn("scene{ } junk").is_err());
    assert!(parse_scn("scene{ object = primobj{ shape = sphere{ radius = 1e999 } } }").is_err());
}

#[test]
fn groups_comments_and_degenerate_triangles() {
    let s = parse_scn(
        "# a comment\nscene{ /* block */ object = group{ object = primobj{ shape = sphere{} }\n \
         object = polyobj{ shape = trilist{ {{0,0,0},{1,1,1},{2,2,2}} } } } };",
    )
    .unwrap();
    assert_eq!(s.objects.len(), 2);
    // The degenerate triangle is skipped when compiling, not a panic.
    let w = crate::World::new(&s);
    assert_eq!(w.skipped, 1);
    assert_eq!(w.primitive_count(), 1);
}

/// Regression (fuzzing): thousands of nested `{` overflowed the stack of the recursive parser;
/// now an error at the first brace past the limit. Run on a 2 MiB thread, the stack a node
/// gets on the engine's workers.
#[test]
fn deep_nesting_is_an_error_not_a_stack_overflow() {
    let r = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let deep = format!("scene{{ object = {} }}", "{".repeat(50_000));
            error_at(&deep)
        })
        .unwrap()
        .join()
        .unwrap();
    let (line, col, message) = r;
    assert_eq!((line, col), (1, 18 + MAX_DEPTH - 1), "{message}");
    assert!(message.contains("nested deeper than 64"), "{message}");
    // 64 levels are fine.
    let ok = format!(
        "scene{{ camera = view {{ from = {{0, 0, 0}}, at = {{0, 0, 1}}, up = {{0, 1, 0}} }}, x = {}1{} }}",
        "{".repeat(60),
        "}".repeat(60)
    );
    assert!(parse_scn(&ok).is_ok() || !error_at(&ok).2.contains("nested"));
}
