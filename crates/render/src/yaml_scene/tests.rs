use super::*;

const SCENE: &str = "\
camera:
  look_at: {from: [0, 1, 4], at: [0, 0.5, 0], fov: 50}
  size: [64, 36]
materials:
  red: {type: lambert, albedo: [0.8, 0.1, 0.1]}
  gloss: {type: plastic, kd: 0.5, ks: 0.4, se: 40}
objects:
  - sphere: {center: [0, 0.5, 0], radius: 0.5}
    material: red
  - quad: {corner: [-5, 0, -5], edge1: [10, 0, 0], edge2: [0, 0, 10]}
    material: {type: lambert, albedo: 0.5}
    catcher: true
  - obj: tri.obj
    material: gloss
    transform: {scale: 2, rotate: [0, 90, 0], translate: [1, 0, 0]}
  - polygon: [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    material: {type: mirror}
lights:
  - radiance: [10, 10, 10]
    quad: {corner: [-0.5, 3, -0.5], edge1: [1, 0, 0], edge2: [0, 0, 1]}
dome:
  image: sky.hdr
  orientation: {orig: [1, 0, 0], south: [0, 1, 0]}
  scale: 2
";

fn with_obj() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    dir
}

#[test]
fn reads_every_construct() {
    let dir = with_obj();
    let y = parse_yaml_scene(SCENE, dir.path()).unwrap();
    let s = &y.scene;
    assert_eq!(
        (
            s.camera.as_ref().unwrap().width,
            s.camera.as_ref().unwrap().height
        ),
        (64, 36)
    );
    // The target projects to the image centre.
    let (u, v) = s
        .camera
        .as_ref()
        .unwrap()
        .project(Vec3::new(0.0, 0.5, 0.0))
        .unwrap();
    assert!(
        (u - 31.5).abs() < 1e-9 && (v - 17.5).abs() < 1e-9,
        "{u} {v}"
    );
    assert_eq!(s.objects.len(), 4);
    assert_eq!(s.catchers().count(), 1);
    assert!(s.objects[1].catcher);
    match &s.objects[0].material {
        Brdf::Lambert(l) => assert_eq!(l.albedo, Rgb::new(0.8, 0.1, 0.1)),
        m => panic!("{m:?}"),
    }
    // Same meaning as .scn plastic.
    assert_eq!(
        s.objects[2].material,
        plastic(0.5, 0.4, 40.0, Rgb::WHITE, Rgb::WHITE)
    );
    // OBJ transform: scale 2, rotate 90° about y (x → −z), translate +x.
    let Shape::Triangles { triangles } = &s.objects[2].shape else {
        panic!()
    };
    let p = triangles[0][1];
    assert!((p - Vec3::new(1.0, 0.0, -2.0)).length() < 1e-12, "{p:?}");
    // The quad covers its parallelogram: area 100 in two triangles.
    let Shape::Triangles { triangles } = &s.objects[1].shape else {
        panic!()
    };
    let area: f64 = triangles
        .iter()
        .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
        .sum();
    assert!((area - 100.0).abs() < 1e-9);
    assert_eq!(s.lights[0].radiance, Rgb::splat(10.0));
    let d = s.dome.as_ref().unwrap();
    assert_eq!((d.image.as_str(), d.scale), ("sky.hdr", 2.0));
    assert_eq!(d.orig, Vec3::new(1.0, 0.0, 0.0));
    assert_eq!(
        y.files,
        vec![dir.path().join("tri.obj"), dir.path().join("sky.hdr")]
    );
}

#[test]
fn krt_camera_and_constant_dome() {
    let text = "camera:\n  K: [[100, 0, 15.5], [0, 100, 11.5], [0, 0, 1]]\n  R: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\n  t: [0, 0, 5]\n  size: [32, 24]\ndome: {color: [0.5, 0.5, 0.5]}\n";
    let s = parse_yaml_scene(text, Path::new(".")).unwrap().scene;
    assert_eq!(s.camera.as_ref().unwrap().k[0][0], 100.0);
    assert_eq!(s.camera.as_ref().unwrap().t, [0.0, 0.0, 5.0]);
    assert_eq!(s.background, Rgb::splat(0.5));
    assert!(s.dome.is_none());
}

fn error_at(text: &str) -> (usize, usize, String) {
    let dir = with_obj();
    let e = parse_yaml_scene(text, dir.path()).unwrap_err();
    (e.line, e.col, e.message)
}

#[test]
fn errors_point_at_line_and_column() {
    let cam = "camera:\n  look_at: {from: [0, 1, 4], at: [0, 0, 0]}\n  size: [8, 8]\n";
    for (body, line, col, what) in [
        (
            "objects:\n  - sphere: {center: [0, 0, 0], radius: -1}\n",
            5,
            41,
            "radius",
        ),
        (
            "objects:\n  - sphere: {center: [0, 0], radius: 1}\n",
            5,
            22,
            "3 numbers",
        ),
        (
            "objects:\n  - sphere: {center: [0, 0, 0], radius: 1}\n    material: nope\n",
            6,
            15,
            "unknown material `nope`",
        ),
        ("objects:\n  - obj: missing.obj\n", 5, 10, "cannot read"),
        (
            "objects:\n  - obj: tri.obj\n    transform: {scale: 0}\n",
            6,
            24,
            "zero",
        ),
        ("objects:\n  - {}\n", 5, 5, "needs a shape"),
        (
            "lights:\n  - radiance: 1\n    sphere: {center: [0, 0, 0], radius: 1}\n",
            6,
            13,
            "polygons",
        ),
        (
            "materials:\n  a: {type: wood}\n",
            5,
            13,
            "unknown material type",
        ),
        ("dome: {image: a.hdr, color: 1}\n", 4, 29, "not both"),
        ("lamps: []\n", 4, 1, "unknown field `lamps`"),
        ("objects: [\n", 5, 1, ""),
    ] {
        let (l, c, m) = error_at(&format!("{cam}{body}"));
        assert_eq!((l, c), (line, col), "{body}: {m}");
        assert!(m.contains(what), "{m}");
    }
    // An error inside the OBJ file names that file and its line.
    let dir = with_obj();
    std::fs::write(dir.path().join("bad.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
    let e =
        parse_yaml_scene(&format!("{cam}objects:\n  - obj: bad.obj\n"), dir.path()).unwrap_err();
    assert!(e.to_string().contains("bad.obj:2: face corner"), "{e}");
    // A camera block that is there must be whole.
    let e = parse_yaml_scene("camera: {size: [8, 8]}\n", dir.path()).unwrap_err();
    assert!(e.message.contains("needs `look_at` or `K`"), "{e}");
}

/// `camera:` is optional: a scene to be seen through a solved camera path has none.
#[test]
fn a_scene_without_a_camera_reads() {
    let dir = with_obj();
    let y = parse_yaml_scene(
        "objects:\n  - sphere: {center: [0, 0, 0], radius: 1}\n",
        dir.path(),
    )
    .unwrap();
    assert!(y.scene.camera.is_none());
    assert_eq!(y.scene.objects.len(), 1);
}

#[test]
fn the_example_scene_of_the_repository_reads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../graphs/scenes");
    let text = std::fs::read_to_string(dir.join("spheres_dome.yaml")).unwrap();
    let y = parse_yaml_scene(&text, &dir).unwrap();
    assert_eq!(y.scene.objects.len(), 5);
    assert_eq!(y.scene.catchers().count(), 1);
    // The OBJ cube: 6 quads = 12 triangles.
    let Shape::Triangles { triangles } = &y.scene.objects[3].shape else {
        panic!()
    };
    assert_eq!(triangles.len(), 12);
    assert!(y.files.iter().all(|f| f.is_file()), "{:?}", y.files);
}

#[test]
fn textures_read_and_errors_point_at_them() {
    let cam = "camera:\n  look_at: {from: [0, 1, 4], at: [0, 0, 0]}\n  size: [8, 8]\n";
    let dir = with_obj();
    let text = format!(
        "{cam}objects:\n  - quad: {{corner: [-5, 0, -5], edge1: [10, 0, 0], edge2: [0, 0, 10]}}\n    texture: {{type: cells, size: 0.2, contrast: 0.8, seed: 1}}\n  - sphere: {{center: [0, 1, 0], radius: 1}}\n    texture: {{type: checker, size: 0.5, contrast: 0.3}}\n  - sphere: {{center: [0, 1, 0], radius: 1}}\n"
    );
    let y = parse_yaml_scene(&text, dir.path()).unwrap();
    assert_eq!(
        y.scene.objects[0].texture,
        Some(Texture::Cells {
            size: 0.2,
            contrast: 0.8,
            seed: 1,
            color: false
        })
    );
    assert_eq!(
        y.scene.objects[1].texture,
        Some(Texture::Checker {
            size: 0.5,
            contrast: 0.3
        })
    );
    assert_eq!(y.scene.objects[2].texture, None);
    let sphere = "objects:\n  - sphere: {center: [0, 0, 0], radius: 1}\n    texture: ";
    for (t, col, what) in [
        ("{type: wood}", 21, "unknown texture type"),
        ("{size: 1}", 14, "missing `type`"),
        ("{type: cells, size: 0}", 14, "size must be > 0"),
        ("{type: cells, size: 1, contrast: 2}", 14, "contrast"),
        ("{type: cells, size: 1, seed: 1.5}", 43, "whole number"),
        (
            "{type: checker, size: 1, seed: 1}",
            39,
            "unknown field `seed`",
        ),
    ] {
        let (l, c, m) = error_at(&format!("{cam}{sphere}{t}\n"));
        assert_eq!((l, c), (6, col), "{t}: {m}");
        assert!(m.contains(what), "{m}");
    }
}

/// Regression (found in review, reproduced with the fuzz harness): tens of thousands of nested
/// collections made a tree whose recursive drop overflowed a 2 MiB stack; now an error where
/// the nesting crosses the limit.
#[test]
fn deep_nesting_is_an_error_not_a_stack_overflow() {
    let (line, col, message) = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| error_at(&format!("camera:\n  size:\n    {}x", "- ".repeat(50_000))))
        .unwrap()
        .join()
        .unwrap();
    assert!(message.contains("nested deeper than 128"), "{message}");
    assert_eq!(line, 3, "{message}");
    assert!(col > 2 * 128, "{col}: {message}");
}

/// An image size over the limit says so, with the figure and the limit (not "two positive
/// whole numbers", which it is); a size that is not two positive whole numbers says that.
#[test]
fn an_oversized_camera_names_the_size_and_the_limit() {
    let scene = |size: &str| {
        format!("camera:\n  look_at: {{from: [0, 1, 4], at: [0, 0, 0]}}\n  size: {size}\n")
    };
    let (line, col, m) = error_at(&scene("[70000, 70000]"));
    assert_eq!((line, col), (3, 9));
    assert!(
        m.contains("[70000, 70000]") && m.contains("over the largest image side, 65536"),
        "{m}"
    );
    let (_, _, m) = error_at(&scene("[0, 10.5]"));
    assert!(
        m.contains("two positive whole numbers") && m.contains("not [0, 10.5]"),
        "{m}"
    );
}
