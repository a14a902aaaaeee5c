//! The box-filtered checker (`checker = { …, filter = "box" }`): a camera
//! ray sees the checker's mean over its footprint on the surface (from its
//! ray differentials), so a floor whose cells shrink below a pixel towards
//! the horizon turns to the mean colour instead of aliasing. Checked by
//! what the picture must do: far rows at the mean colour, less error
//! against a dense reference at one sample a pixel, the same energy, the
//! same bits per pixel alone, in any region split and on any thread count
//! (uniform, lens and adaptive sampling), and the keys checked.

use glam::DVec3;
use prism::render::{Film, Region, render_pixel, render_region};
use prism::settings::Adaptive;
use prism::shading::whitted::{Whitted, WhittedSettings};
use prism::{RenderSettings, Scene, render};

/// A white / black checker floor of cells 0.5 seen at a low angle, lit by
/// ambient light only, so a pixel is the checker's colour itself.
fn floor(filter: &str, camera_extra: &str) -> Scene {
    let text = format!(
        r#"
[render]
width = 96
height = 48
spp = 1
background = [0, 0, 0]
ambient = [1, 1, 1]
[camera]
position = [0.3, 1.0, 6.0]
look_at = [0, 0.6, 0]
fov = 50
{camera_extra}
[materials.floor]
color = [1, 1, 1]
ka = 1
kd = 0
checker = {{ color = [0, 0, 0], size = 0.5{filter} }}
[[objects]]
type = "plane"
normal = [0, 1, 0]
distance = 0
material = "floor"
"#
    );
    Scene::from_toml(&text, "floor.toml").unwrap_or_else(|e| panic!("{e}"))
}

fn filtered() -> Scene {
    floor(r#", filter = "box""#, "")
}

fn point_sampled() -> Scene {
    floor("", "")
}

/// The mean of rows `rows` of the picture.
fn mean(f: &Film, rows: std::ops::Range<u32>) -> f64 {
    let n = rows.len() as f64 * 96.0;
    rows.flat_map(|y| (0..96).map(move |x| (x, y)))
        .map(|(x, y)| f.get(x, y).x)
        .sum::<f64>()
        / n
}

#[test]
fn far_rows_turn_to_the_mean_colour_and_the_error_falls() {
    let (filtered, point) = (filtered(), point_sampled());
    let reference = render(
        &point,
        &RenderSettings {
            spp: 256,
            seed: 7,
            ..point.settings
        },
        &(),
    )
    .unwrap()
    .film;
    let f = render(&filtered, &filtered.settings, &()).unwrap().film;
    let p = render(&point, &point.settings, &()).unwrap().film;
    // The horizon lies near row 16 of 48: the floor's first rows below it
    // hold cells far smaller than a pixel.
    let horizon = (0..48)
        .find(|&y| reference.get(48, y).x > 0.0)
        .expect("the floor is in view");
    let far = horizon + 1..horizon + 4;
    let spread = |film: &Film| {
        far.clone()
            .flat_map(|y| (0..96).map(move |x| (x, y)))
            .map(|(x, y)| (film.get(x, y).x - 0.5).abs())
            .fold(0.0, f64::max)
    };
    // Point samples there are black or white; the filtered ones grey.
    assert_eq!(spread(&p), 0.5);
    assert!(spread(&f) < 0.1, "filtered far rows: {}", spread(&f));
    let (ef, ep) = (f.rmse(&reference), p.rmse(&reference));
    eprintln!("1 spp against 256 spp: filtered {ef:.4}, point-sampled {ep:.4}");
    assert!(ef < 0.6 * ep, "{ef} against {ep}");
    // A box filter moves no energy: the floor's mean (below the row the
    // horizon cuts, whose coverage one sample cannot tell) stays the
    // reference's.
    let floor_rows = horizon + 1..48;
    let (mf, mr) = (mean(&f, floor_rows.clone()), mean(&reference, floor_rows));
    assert!((mf - mr).abs() < 0.01 * mr, "{mf} against {mr}");
}

#[test]
fn every_pixel_alone_region_and_thread_count_gives_the_same_bits() {
    let lens = floor(r#", filter = "box""#, "aperture = 0.05\nfocus_distance = 5");
    let scenes = [filtered(), lens];
    for s in &scenes {
        for spp in [1, 5] {
            for adaptive in [
                None,
                Some(Adaptive {
                    threshold: 0.05,
                    depth: 2,
                    jitter: false,
                }),
            ] {
                let settings = RenderSettings {
                    spp,
                    adaptive,
                    threads: Some(2),
                    ..s.settings
                };
                let whole = render(s, &settings, &()).unwrap().film;
                let one = render(
                    s,
                    &RenderSettings {
                        threads: Some(1),
                        ..settings
                    },
                    &(),
                )
                .unwrap()
                .film;
                assert_eq!(whole.pixels(), one.pixels());
                let region = Region::crop(13, 70, 9, 37, 96, 48).unwrap();
                let part = render_region(s, &settings, region, &()).unwrap().film;
                let tracer = Whitted::new(
                    s,
                    WhittedSettings {
                        max_depth: settings.max_depth,
                        min_weight: settings.min_weight,
                    },
                );
                let mut stats = Default::default();
                for y in region.y0..region.y1 {
                    for x in region.x0..region.x1 {
                        assert_eq!(part.get(x, y), whole.get(x, y), "pixel {x},{y}");
                        if (x + y) % 7 == 0 {
                            let alone = render_pixel(s, &tracer, &settings, x, y, &mut stats);
                            assert_eq!(alone, whole.get(x, y), "pixel {x},{y} alone");
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn the_filter_key_is_checked() {
    let with = |checker: &str| {
        Scene::from_toml(
            &format!(
                "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
                 [materials.m]\ncolor = [1, 1, 1]\nchecker = {{ {checker} }}\n\
                 [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n"
            ),
            "keys.toml",
        )
    };
    assert!(with(r#"color = [0, 0, 0], filter = "none""#).is_ok());
    assert!(with(r#"color = [0, 0, 0], filter = "box""#).is_ok());
    let unknown = with(r#"color = [0, 0, 0], filter = "gauss""#)
        .unwrap_err()
        .to_string();
    assert!(
        unknown.contains("keys.toml:6") && unknown.contains("box"),
        "{unknown}"
    );
    let uv = with(r#"color = [0, 0, 0], mapping = "uv", filter = "box""#)
        .unwrap_err()
        .to_string();
    assert!(
        uv.contains("keys.toml:6") && uv.contains("world checker"),
        "{uv}"
    );
}

#[test]
fn a_scene_without_a_filtered_texture_asks_for_no_differentials() {
    let point = point_sampled();
    let settings = WhittedSettings {
        max_depth: 4,
        min_weight: 0.0,
    };
    assert!(!Whitted::new(&point, settings).wants_differentials());
    assert!(Whitted::new(&filtered(), settings).wants_differentials());
    // Colours of the cells are what the material says.
    let p = render(&point, &point.settings, &()).unwrap().film;
    assert!(
        p.pixels()
            .iter()
            .all(|c| *c == DVec3::ZERO || *c == DVec3::ONE)
    );
}
