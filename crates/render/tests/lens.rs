//! Renders through a lens: a camera carrying a Brown–Conrady distortion traces each
//! pixel's ray through the undistorted point of that pixel, so its render is the pinhole render
//! of the same scene resampled through the lens — checked here against the renderer's own noise
//! estimate — and a camera without a lens renders as before.

use vfxgraph_lens::Distortion;
use vfxgraph_render::texture::PlanarMap;
use vfxgraph_render::*;

/// The lens of `blender_plate_dev/distorted` (its README).
const LENS: Distortion = Distortion::BrownConrady {
    k1: -0.16,
    k2: 0.045,
    k3: 0.0,
    p1: 0.0008,
    p2: -0.0005,
};

/// A ground plane with a smooth planar texture (a product of sines, ~1 m periods, per channel)
/// under a constant sky: an image with no edges, so bilinear resampling is near exact.
fn scene() -> Scene {
    let p = |x: f64, y: f64| Vec3::new(x, y, 0.0);
    let (n, m) = (48, 48);
    let mut texels = Vec::with_capacity(3 * n * m);
    for j in 0..m {
        for i in 0..n {
            for c in 0..3 {
                let (a, b) = (i as f64, j as f64 * 0.8 + c as f64);
                texels.push((0.55 + 0.4 * a.sin() * b.cos()) as f32);
            }
        }
    }
    let mut ground = Object::new(
        Shape::Triangles {
            triangles: vec![
                [p(-4.0, -4.0), p(4.0, -4.0), p(4.0, 4.0)],
                [p(-4.0, -4.0), p(4.0, 4.0), p(-4.0, 4.0)],
            ],
        },
        Brdf::Lambert(Lambert {
            albedo: Rgb::splat(0.9),
        }),
    );
    ground.texture = Some(Texture::Planar(PlanarMap {
        origin: Vec3::new(-4.0, -4.0, 0.0),
        u: Vec3::new(8.0, 0.0, 0.0),
        v: Vec3::new(0.0, 8.0, 0.0),
        width: n,
        height: m,
        texels,
    }));
    Scene {
        camera: None,
        objects: vec![ground],
        lights: vec![],
        background: Rgb::BLACK,
        dome: None,
    }
}

fn pinhole() -> Camera {
    Camera::look_at(
        Vec3::new(0.4, -2.2, 1.6),
        Vec3::new(0.0, 0.3, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        60.0,
        96,
        72,
    )
    .unwrap()
}

fn render_with(camera: &Camera) -> RenderOutput {
    let world = World::new(&scene());
    let env = ConstantEnvironment {
        radiance: Rgb::splat(1.0),
    };
    let settings = RenderSettings {
        spp: 64,
        max_depth: 2,
        seed: 7,
        ..RenderSettings::default()
    };
    render(&world, &env, camera, &settings, &|_| {}, None).unwrap()
}

/// Bilinear sample of channel `c` at pixel position (x, y); `None` outside the pixel centres.
fn sample(img: &vfxgraph_imaging::Image, x: f64, y: f64, c: usize) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0 && x <= (img.width - 1) as f64 && y <= (img.height - 1) as f64) {
        return None;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(img.width - 1), (y0 + 1).min(img.height - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let g = |x, y| img.get(x, y, c) as f64;
    Some(
        (g(x0, y0) * (1.0 - fx) + g(x1, y0) * fx) * (1.0 - fy)
            + (g(x0, y1) * (1.0 - fx) + g(x1, y1) * fx) * fy,
    )
}

/// RMS over the compared pixels of (lens render − pinhole render sampled at `at(x, y)`) divided
/// by the two renders' standard errors; and how many pixels were compared.
fn rms_z(
    lens: &RenderOutput,
    pin: &RenderOutput,
    at: impl Fn(f64, f64) -> (f64, f64),
) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0);
    let img = &lens.image;
    for y in 0..img.height {
        for x in 0..img.width {
            let (px, py) = at(x as f64, y as f64);
            for c in 0..3 {
                let (Some(v), Some(var)) = (
                    sample(&pin.image, px, py, c),
                    sample(&pin.variance, px, py, c),
                ) else {
                    continue;
                };
                let d = img.get(x, y, c) as f64 - v;
                let s2 = lens.variance.get(x, y, c) as f64 + var + 1e-8;
                sum += d * d / s2;
                n += 1;
            }
        }
    }
    ((sum / n as f64).sqrt(), n)
}

/// The render through the lens is the pinhole render resampled at K·undistort(K⁻¹x) within the
/// Monte Carlo noise (RMS z 0.78 measured; bound 1.5), while comparing it with the pinhole render
/// pixel for pixel (as if the lens were ignored) is outside it (RMS z 3.6; bound 2.5).
#[test]
fn a_lens_render_is_the_pinhole_render_resampled_through_the_lens() {
    let pin_cam = pinhole();
    let lens_cam = pin_cam.clone().with_distortion(LENS).unwrap();
    let (pin, lens) = (render_with(&pin_cam), render_with(&lens_cam));
    let k = pin_cam.k;
    let through = |x: f64, y: f64| {
        let q = [(x - k[0][2]) / k[0][0], (y - k[1][2]) / k[1][1]];
        let p = LENS.undistort(q).unwrap();
        (k[0][0] * p[0] + k[0][2], k[1][1] * p[1] + k[1][2])
    };
    let (z, n) = rms_z(&lens, &pin, through);
    let (z_naive, _) = rms_z(&lens, &pin, |x, y| (x, y));
    eprintln!("through the lens: RMS z {z:.3} over {n} samples; lens ignored: {z_naive:.1}");
    assert!(n > 3 * 96 * 72 * 8 / 10, "only {n} samples compared");
    assert!(z < 1.5, "lens render vs resampled pinhole: RMS z {z}");
    assert!(z_naive > 2.5, "the lens changes the render: {z_naive}");
}

/// A world point projects through the lens (K·distort of its normalized point, OpenCV's
/// formula), and the primary ray through that pixel position passes through the point.
#[test]
fn a_projected_point_lands_on_the_distorted_pixel_and_its_ray_hits_it() {
    let cam = pinhole().with_distortion(LENS).unwrap();
    let k = cam.k;
    let gen = cam.rays();
    // Points the pinhole sees near three corners and an edge, 2–4 m away.
    let pin = pinhole().rays();
    for (x, y, t) in [
        (4.0, 5.0, 2.0),
        (90.0, 66.0, 2.5),
        (8.0, 64.0, 3.0),
        (50.0, 2.0, 4.0),
    ] {
        let pt = pin.ray(x, y).at(t);
        let (x, y) = cam.project(pt).unwrap();
        // By hand: camera coordinates, normalized point, OpenCV's Brown–Conrady, K.
        let (r, t) = (cam.r, cam.t);
        let pc: Vec<f64> = (0..3)
            .map(|i| r[i][0] * pt.x + r[i][1] * pt.y + r[i][2] * pt.z + t[i])
            .collect();
        let (u, v) = (pc[0] / pc[2], pc[1] / pc[2]);
        let r2 = u * u + v * v;
        let rho = 1.0 - 0.16 * r2 + 0.045 * r2 * r2;
        let qu = u * rho + 2.0 * 0.0008 * u * v - 0.0005 * (r2 + 2.0 * u * u);
        let qv = v * rho + 0.0008 * (r2 + 2.0 * v * v) - 2.0 * 0.0005 * u * v;
        let (wx, wy) = (k[0][0] * qu + k[0][2], k[1][1] * qv + k[1][2]);
        assert!(
            (x - wx).abs() < 1e-9 && (y - wy).abs() < 1e-9,
            "{x} {y} vs {wx} {wy}"
        );
        // The pinhole would put it elsewhere (the lens moves it by pixels here).
        let (px, py) = pinhole().project(pt).unwrap();
        assert!((px - x).hypot(py - y) > 0.5, "{px} {py} vs {x} {y}");
        let ray = gen.ray(x, y);
        let to = pt - ray.o;
        let along = to.dot(ray.d);
        let miss = (to - ray.d * along).length();
        assert!(
            miss < 1e-9 * to.length(),
            "the ray misses the point by {miss}"
        );
    }
}

/// A camera without a lens, or with every coefficient zero, renders exactly as before the lens
/// existed (the pinhole code path, bit for bit).
#[test]
fn a_zero_lens_renders_the_pinhole_bit_for_bit() {
    let pin = render_with(&pinhole());
    let zero = Distortion::BrownConrady {
        k1: 0.0,
        k2: 0.0,
        k3: 0.0,
        p1: 0.0,
        p2: 0.0,
    };
    let same = render_with(&pinhole().with_distortion(zero).unwrap());
    assert_eq!(pin.image.data, same.image.data);
}

/// A lens that folds over inside the frame is refused with the camera.
#[test]
fn a_folding_lens_is_a_camera_error() {
    let fold = Distortion::BrownConrady {
        k1: -0.9,
        k2: 0.0,
        k3: 0.0,
        p1: 0.0,
        p2: 0.0,
    };
    let e = pinhole().with_distortion(fold).unwrap_err().to_string();
    assert!(e.contains("lens"), "{e}");
}

/// A render whose image would be over the image limit is refused before a tile is traced
/// (a 65536 × 65536 render used to buffer every tile first); the error names the size.
#[test]
fn a_giant_render_is_refused_before_tracing() {
    let camera = Camera::look_at(
        Vec3::new(0.4, -2.2, 1.6),
        Vec3::new(0.0, 0.3, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        60.0,
        65536,
        65536,
    )
    .unwrap();
    let world = World::new(&scene());
    let env = ConstantEnvironment {
        radiance: Rgb::splat(1.0),
    };
    let traced = std::sync::atomic::AtomicBool::new(false);
    let Err(e) = render(
        &world,
        &env,
        &camera,
        &RenderSettings::default(),
        &|_| traced.store(true, std::sync::atomic::Ordering::Relaxed),
        None,
    ) else {
        panic!("a 65536×65536 render was accepted")
    };
    assert!(e.to_string().contains("65536×65536"), "{e}");
    assert!(
        !traced.load(std::sync::atomic::Ordering::Relaxed),
        "no tile was traced"
    );
}
