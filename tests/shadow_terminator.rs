//! The shadow terminator: a smooth-shaded low-poly sphere shades like the
//! sphere its normals describe. Without Hanika's offset the flat facets
//! shadow their own smoothed normals near the terminator and the light
//! ends in stair-steps along it.

use std::fmt::Write as _;
use std::path::Path;

use prism::math::transcendental::sin_cos;
use prism::{RenderSettings, Scene, render};

const SIZE: u32 = 241;
/// Half the orthographic view's height: the unit sphere and a margin.
const HALF_VIEW: f64 = 1.1;

/// A UV sphere of unit radius about the y axis (`segments` around,
/// `rings` pole to pole) as OBJ, with vertex normals (`smooth`) or none.
fn uv_sphere_obj(segments: usize, rings: usize, smooth: bool) -> String {
    let mut obj = String::new();
    let index = |ring: usize, segment: usize| 1 + ring * (segments + 1) + segment;
    for ring in 0..=rings {
        let polar = std::f64::consts::PI * ring as f64 / rings as f64;
        for segment in 0..=segments {
            let azimuth = std::f64::consts::TAU * segment as f64 / segments as f64;
            let ((sp, cp), (sa, ca)) = (sin_cos(polar), sin_cos(azimuth));
            let p = [sp * ca, cp, -sp * sa];
            writeln!(obj, "v {} {} {}", p[0], p[1], p[2]).unwrap();
            writeln!(obj, "vn {} {} {}", p[0], p[1], p[2]).unwrap();
        }
    }
    let corner = |i: usize| {
        if smooth {
            format!("{i}//{i}")
        } else {
            i.to_string()
        }
    };
    for ring in 0..rings {
        for segment in 0..segments {
            let (a, b) = (index(ring, segment), index(ring, segment + 1));
            let (c, d) = (index(ring + 1, segment + 1), index(ring + 1, segment));
            // Counter-clockwise from outside; the poles' degenerate halves
            // left out.
            if ring > 0 {
                writeln!(obj, "f {} {} {}", corner(a), corner(d), corner(b)).unwrap();
            }
            if ring + 1 < rings {
                writeln!(obj, "f {} {} {}", corner(b), corner(d), corner(c)).unwrap();
            }
        }
    }
    obj
}

/// The sphere (a mesh `file`, or the analytic sphere) seen from +z,
/// orthographic, lit by a directional light from `towards_light`:
/// a diffuse white surface, no ambient, so a pixel is max(0, N·L).
fn render_sphere(dir: &Path, object: &str, towards_light: [f64; 3]) -> Vec<f64> {
    let [x, y, z] = towards_light.map(|c| -c);
    let toml = format!(
        "[render]\nwidth = {SIZE}\nheight = {SIZE}\nspp = 1\nambient = [0, 0, 0]\n\
         background = [0, 0, 0]\n\
         [camera]\ntype = \"orthographic\"\nposition = [0, 0, 10]\nlook_at = [0, 0, 0]\n\
         view_height = {}\n\
         [materials.white]\nka = 0\nkd = 1\nks = 0\n\
         [lights.sun]\ntype = \"directional\"\ndirection = [{x}, {y}, {z}]\n\
         [[objects]]\nmaterial = \"white\"\n{object}\n",
        2.0 * HALF_VIEW
    );
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    let scene = Scene::load(&dir.join("scene.toml")).unwrap();
    let settings = RenderSettings {
        threads: Some(2),
        ..scene.settings
    };
    let film = render(&scene, &settings, &()).unwrap().film;
    (0..SIZE)
        .flat_map(|y| (0..SIZE).map(move |x| (x, y)))
        .map(|(x, y)| film.get(x, y).x)
        .collect()
}

/// The image-plane position of pixel (x, y)'s centre, in sphere radii.
fn plane_position(x: u32, y: u32) -> (f64, f64) {
    let to_plane = |i: u32| (2.0 * (i as f64 + 0.5) / SIZE as f64 - 1.0) * HALF_VIEW;
    (to_plane(x), -to_plane(y))
}

struct Spheres {
    mesh: Vec<f64>,
    analytic: Vec<f64>,
    towards_light: glam::DVec3,
}

fn spheres(smooth: bool, segments: usize, towards_light: [f64; 3]) -> Spheres {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("sphere.obj");
    std::fs::write(&obj, uv_sphere_obj(segments, segments / 2, smooth)).unwrap();
    Spheres {
        mesh: render_sphere(
            dir.path(),
            "type = \"mesh\"\nfile = \"sphere.obj\"",
            towards_light,
        ),
        analytic: render_sphere(
            dir.path(),
            "type = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1",
            towards_light,
        ),
        towards_light: glam::DVec3::from(towards_light).normalize(),
    }
}

impl Spheres {
    /// The largest |mesh − analytic| over pixels well inside the outline
    /// (the polygon's silhouette differs from the circle's) where the true
    /// sphere's N·L is at least `lit`.
    fn worst_where_lit(&self, lit: f64) -> (f64, (u32, u32)) {
        let mut worst = (0.0, (0, 0));
        for y in 0..SIZE {
            for x in 0..SIZE {
                let (u, v) = plane_position(x, y);
                let r2 = u * u + v * v;
                if r2 > 0.9 * 0.9 {
                    continue;
                }
                let n = glam::DVec3::new(u, v, (1.0 - r2).sqrt());
                if n.dot(self.towards_light) < lit {
                    continue;
                }
                let k = (y * SIZE + x) as usize;
                let error = (self.mesh[k] - self.analytic[k]).abs();
                if error > worst.0 {
                    worst = (error, (x, y));
                }
            }
        }
        worst
    }
}

#[test]
fn a_smooth_low_poly_sphere_shades_as_the_sphere_up_to_its_terminator() {
    // The light from the side and above, so the terminator crosses the
    // facets obliquely (stair-steps, before the offset).
    let s = spheres(true, 32, [1.0, 0.7, 0.35]);
    let (error, at) = s.worst_where_lit(0.01);
    eprintln!("32 segments, smooth: |mesh − sphere| ≤ {error:.4} where N·L ≥ 0.01");
    assert!(error < 0.02, "mesh − sphere up to {error} at {at:?}");
    // Along the meridian facing the camera (the image's middle column),
    // from the terminator up to the brightest point, never darker.
    let x = SIZE / 2;
    let column: Vec<(f64, f64)> = (0..SIZE)
        .rev()
        .filter_map(|y| {
            let (u, v) = plane_position(x, y);
            let n = glam::DVec3::new(u, v, (1.0 - u * u - v * v).max(0.0).sqrt());
            (v.abs() < 0.95 && n.dot(s.towards_light) > -0.2)
                .then(|| (n.dot(s.towards_light), s.mesh[(y * SIZE + x) as usize]))
        })
        .collect();
    let peak = column
        .iter()
        .position(|c| c.1 == column.iter().map(|c| c.1).fold(0.0, f64::max))
        .unwrap();
    for pair in column[..=peak].windows(2) {
        assert!(
            pair[1].1 >= pair[0].1 - 1e-3,
            "brightness falls along the meridian: {pair:?}"
        );
    }
}

#[test]
fn flat_and_fine_meshes_keep_their_shadows() {
    // A flat-shaded sphere has nothing to offset: its facets stay as the
    // facets' own N·L.
    let flat = spheres(false, 32, [1.0, 0.7, 0.35]);
    let (error, at) = flat.worst_where_lit(0.05);
    eprintln!("32 segments, flat: |mesh − sphere| up to {error:.4} where N·L ≥ 0.05");
    assert!(error > 0.05, "facets should show: {error} at {at:?}");
    // A fine smooth sphere was already close; it stays so.
    let fine = spheres(true, 256, [1.0, 0.7, 0.35]);
    let (error, at) = fine.worst_where_lit(0.05);
    eprintln!("256 segments, smooth: |mesh − sphere| ≤ {error:.4} where N·L ≥ 0.05");
    assert!(error < 0.01, "fine mesh − sphere up to {error} at {at:?}");
}
