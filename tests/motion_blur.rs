//! An open shutter (`[render] shutter`): a sphere moving at constant speed
//! leaves a streak whose length and box profile are analytic; nothing
//! changes where nothing moves; the same bits on every thread count and
//! region; keys checked.

use prism::render::{Region, render_region};
use prism::{RenderSettings, Scene, render};

fn scene(toml: &str) -> Scene {
    Scene::from_toml(toml, "test").unwrap_or_else(|e| panic!("{e}"))
}

/// A white ball of radius 0.5, lit only by ambient light (white on black),
/// moving along x from −1.5 at frame 0 to +1.5 at frame 1, seen from above
/// by an orthographic camera 6 units wide: 20 pixels a unit.
fn moving_ball(render_extra: &str) -> Scene {
    scene(&format!(
        r#"
        [render]
        width = 120
        height = 40
        spp = 64
        ambient = [1, 1, 1]
        {render_extra}
        [animation]
        frames = 2
        [camera]
        type = "orthographic"
        position = [0, 0, 10]
        look_at = [0, 0, 0]
        view_height = 2
        [materials.white]
        ka = 1
        kd = 0
        [[objects]]
        type = "sphere"
        material = "white"
        radius = 0.5
        transform = [{{ translate = [{{ frame = 0, value = [-1.5, 0, 0] }}, {{ frame = 1, value = [1.5, 0, 0] }}] }}]
        "#
    ))
}

#[test]
fn a_moving_ball_leaves_a_streak_of_analytic_length_and_box_profile() {
    let s = moving_ball("shutter = [0, 1]\nshutter_samples = 128");
    assert_eq!(s.motion.len(), 128);
    let film = render(&s, &s.settings, &()).unwrap().film;
    // Along the row through the centre, a point x is covered while the
    // centre c(τ) = −1.5 + 3τ is within 0.5 of it: for the share of the
    // exposure |[x − 0.5, x + 0.5] ∩ [−1.5, 1.5]| / 3 (a box of length 3
    // convolved with the ball's chord 1: ramps 1 long at each end, a
    // plateau of 1/3 between).
    let row = 20;
    let mut worst: f64 = 0.0;
    for px in 0..120u32 {
        let x = (f64::from(px) + 0.5) / 20.0 - 3.0;
        let covered = ((x + 0.5).min(1.5) - (x - 0.5).max(-1.5)).max(0.0) / 3.0;
        let got = film.pixels()[(row * 120 + px) as usize].x;
        worst = worst.max((got - covered).abs());
    }
    // 64 stratified times a pixel over 128 instants: the shares are right
    // to about 1/64, the instants to 1/128 of the travel.
    eprintln!("streak profile: worst |measured − analytic| = {worst:.4}");
    assert!(worst < 0.035, "{worst}");
    // The streak's length: lit pixels on that row span the travel plus the
    // diameter, 3 + 1 = 4 units, 80 pixels.
    let lit = (0..120u32)
        .filter(|&px| film.pixels()[(row * 120 + px) as usize].x > 0.0)
        .count();
    assert!((79..=81).contains(&lit), "{lit}");
}

#[test]
fn with_the_shutter_closed_or_nothing_moving_the_picture_keeps_its_bits() {
    let closed = moving_ball("");
    assert!(closed.motion.is_empty());
    let still = scene(
        "[render]\nwidth = 32\nheight = 24\nspp = 4\nshutter = [0, 1]\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n[materials.m]\n",
    );
    // Nothing keyed: no instants, the same bits as without a shutter.
    assert!(still.motion.is_empty());
    let plain = scene(
        "[render]\nwidth = 32\nheight = 24\nspp = 4\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n[materials.m]\n",
    );
    let a = render(&still, &still.settings, &()).unwrap().film;
    let b = render(&plain, &plain.settings, &()).unwrap().film;
    assert_eq!(a.pixels(), b.pixels());
}

#[test]
fn a_streak_renders_the_same_bits_on_any_thread_count_and_region() {
    let s = moving_ball("shutter = [0.25, 0.75]\nshutter_samples = 8");
    let whole = render(
        &s,
        &RenderSettings {
            threads: Some(2),
            ..s.settings
        },
        &(),
    )
    .unwrap()
    .film;
    let one = render(
        &s,
        &RenderSettings {
            threads: Some(1),
            ..s.settings
        },
        &(),
    )
    .unwrap()
    .film;
    assert_eq!(whole.pixels(), one.pixels());
    let region = Region {
        x0: 33,
        x1: 90,
        y0: 7,
        y1: 31,
    };
    let part = render_region(&s, &s.settings, region, &()).unwrap().film;
    for y in 7..31u32 {
        for x in 33..90u32 {
            assert_eq!(
                part.pixels()[((y - 7) * 57 + (x - 33)) as usize],
                whole.pixels()[(y * 120 + x) as usize]
            );
        }
    }
    // Adaptive sampling takes its own instants, keyed by lattice points.
    let adaptive = moving_ball(
        "shutter = [0, 1]\nshutter_samples = 8\nadaptive = { threshold = 0.1, depth = 2 }",
    );
    let a = render(&adaptive, &adaptive.settings, &()).unwrap().film;
    let b = render_region(&adaptive, &adaptive.settings, region, &())
        .unwrap()
        .film;
    for y in 7..31u32 {
        for x in 33..90u32 {
            assert_eq!(
                b.pixels()[((y - 7) * 57 + (x - 33)) as usize],
                a.pixels()[(y * 120 + x) as usize]
            );
        }
    }
}

#[test]
fn shutter_keys_are_checked() {
    let err = |render: &str| {
        Scene::from_toml(
            &format!("[render]\n{render}\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n"),
            "test",
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default()
    };
    assert!(err("shutter = [1, 0]").contains("`shutter`"));
    assert!(err("shutter_samples = 4").contains("needs `shutter"));
    assert!(err("shutter = [0, 1]\nshutter_samples = 0").contains("shutter_samples"));
    assert!(err("shutter = [0, 1]\nshutter_samples = 100000").contains("shutter_samples"));
}

#[test]
fn explain_names_the_instant_a_sample_sees() {
    let s = moving_ball("shutter = [0.25, 0.75]\nshutter_samples = 8");
    let instants: Vec<f64> = (0..8).map(|k| 0.25 + (f64::from(k) + 0.5) / 16.0).collect();
    let mut seen = std::collections::BTreeSet::new();
    for sample in 0..64 {
        let e = prism::render::explain::explain(&s, &s.settings, 60, 20, sample).unwrap();
        let t = e.time.expect("an instant");
        let k = instants
            .iter()
            .position(|&i| (i - t).abs() < 1e-12)
            .expect("one of the instants");
        seen.insert(k);
    }
    // 64 stratified samples over 8 instants: every instant is seen.
    assert_eq!(seen.len(), 8);
    let still = moving_ball("");
    assert_eq!(
        prism::render::explain::explain(&still, &still.settings, 60, 20, 0)
            .unwrap()
            .time,
        None
    );
}

#[test]
fn too_many_instants_of_a_big_scene_are_refused_before_they_are_built() {
    // 200,000 spheres (about 20 MiB) at 256 instants would take 5 GiB:
    // refused at the `shutter` key, with what to lower.
    let mut text = String::new();
    let head = "[render]\nwidth = 8\nheight = 8\nshutter = [0, 1]\nshutter_samples = 256\n[animation]\nframes = 1\n\
                [camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n[materials.m]\n";
    text.push_str(head);
    for i in 0..200_000 {
        text.push_str(&format!(
            "[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\ncenter = [{}, {}, {}]\nradius = 0.1\n",
            i % 100,
            i / 100 % 100,
            i / 10_000
        ));
    }
    text.push_str(
        "[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\nradius = 0.1\n\
         transform = [{ translate = [{ frame = 0, value = [0, 0, 0] }, { frame = 1, value = [1, 0, 0] }] }]\n",
    );
    let Err(e) = Scene::from_toml(&text, "big.toml") else {
        panic!("256 instants of 20 MiB were built");
    };
    let e = e.to_string();
    assert!(
        e.contains("big.toml:4:1") && e.contains("lower `shutter_samples`"),
        "{e}"
    );
    // At 2 instants it fits.
    let fits = text.replace("shutter_samples = 256", "shutter_samples = 2");
    assert!(Scene::from_toml(&fits, "big.toml").is_ok_and(|s| s.motion.len() == 2));
}
