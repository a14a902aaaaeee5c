//! `prism explain`: the ray tree of one sample of one pixel, with the
//! terms of the Whitted formula at every hit, as text or JSON.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use prism::Scene;
use prism::render::explain::{Explanation, IntersectionSteps, RayNode, explain};

use super::render::SettingsArgs;
use super::{BAD_INPUT, LoadArgs, report_scene_error};

#[derive(Args)]
pub struct ExplainArgs {
    /// Scene file (TOML); the built-in demo scene when omitted.
    scene: Option<PathBuf>,
    /// The pixel, counted from the top-left corner.
    #[arg(long, value_name = "X,Y", value_parser = parse_pixel)]
    pixel: (u32, u32),
    /// Which of the pixel's samples (0-based).
    #[arg(long, default_value_t = 0)]
    sample: usize,
    /// Animation frame.
    #[arg(long, default_value_t = 0)]
    frame: u32,
    /// One JSON object (its `radiance` is the sample's RGB) instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    overrides: SettingsArgs,
    #[command(flatten)]
    load: LoadArgs,
}

fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let (x, y) = s.split_once(',').ok_or("expected X,Y, e.g. 320,240")?;
    Ok((
        x.trim()
            .parse()
            .map_err(|_| "expected X,Y with whole numbers")?,
        y.trim()
            .parse()
            .map_err(|_| "expected X,Y with whole numbers")?,
    ))
}

pub fn explain_command(args: &ExplainArgs) -> ExitCode {
    let mut options = match args.load.options() {
        Ok(o) => o,
        Err(e) => {
            say_err!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    options.frame = args.frame;
    let scene = match &args.scene {
        Some(path) => match Scene::load_with(path, &options) {
            Ok(s) => s,
            Err(e) => return report_scene_error(&e),
        },
        None => Scene::demo(),
    };
    let settings = match args.overrides.apply(&scene.settings) {
        Ok(s) => prism::RenderSettings {
            frame: args.frame,
            ..s
        },
        Err(e) => {
            say_err!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let (x, y) = args.pixel;
    let explanation = match explain(&scene, &settings, x, y, args.sample) {
        Ok(e) => e,
        Err(e) => {
            say_err!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let text = if args.json {
        json_for_terminal(&serde_json::to_string_pretty(&explanation).unwrap_or_default())
    } else {
        describe(&explanation)
    };
    // A reader that stops early (`| head`) is not an error.
    let _ = writeln!(std::io::stdout().lock(), "{text}");
    ExitCode::SUCCESS
}

/// JSON with every character a terminal must not get raw written as a
/// `\uXXXX` escape (serde_json escapes only those below U+0020; DEL, the
/// C1 controls and bidi overrides in names would pass): the same JSON.
fn json_for_terminal(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for c in json.chars() {
        // The pretty-printer's own line breaks stay; one inside a string
        // is `\n` already.
        if c != '\n' && prism::text::is_unsafe_on_terminal(c) {
            // All of them lie in the Basic Multilingual Plane.
            out.push_str(&format!("\\u{:04x}", c as u32));
        } else {
            out.push(c);
        }
    }
    out
}

fn rgb(v: [f64; 3]) -> String {
    format!("({:.6}, {:.6}, {:.6})", v[0], v[1], v[2])
}

/// The tree as indented text, one ray per block.
fn describe(e: &Explanation) -> String {
    let mut out = format!(
        "pixel {},{} sample {} of {}: radiance {}{}\n",
        e.pixel[0],
        e.pixel[1],
        e.sample,
        e.samples,
        rgb(e.radiance),
        if e.samples > 1 {
            format!(" (the pixel, over all samples: {})", rgb(e.pixel_radiance))
        } else {
            String::new()
        }
    );
    if let Some(time) = e.time {
        out.push_str(&format!(
            "at the shutter's instant {time:.6} frames after the frame's start\n"
        ));
    }
    if let Some([right, up]) = e.lens_point {
        out.push_str(&format!(
            "through the lens at ({right:.6}, {up:.6}) (right, up from its centre)\n"
        ));
    }
    node(&e.tree, 0, &mut out);
    out
}

fn node(n: &RayNode, indent: usize, out: &mut String) {
    let pad = "  ".repeat(indent);
    let line = |out: &mut String, s: String| {
        out.push_str(&pad);
        // Names from the scene and its models: no raw control characters.
        out.push_str(&prism::text::escape_controls(&s));
        out.push('\n');
    };
    line(
        out,
        format!(
            "{} ray (depth {}, weight {}) from {} towards {}",
            n.kind,
            n.depth,
            rgb(n.weight),
            rgb(n.origin),
            rgb(n.direction)
        ),
    );
    match &n.hit {
        None => line(
            out,
            format!("  misses everything: background {}", rgb(n.radiance)),
        ),
        Some(h) => {
            line(
                out,
                format!(
                    "  hits `{}` (primitive {}, material `{}`) at distance {:.6}, point {}, normal {}, {}{}",
                    h.object,
                    h.primitive,
                    h.material,
                    h.distance,
                    rgb(h.point),
                    rgb(h.normal),
                    if h.entering { "entering" } else { "leaving" },
                    match (h.eta_incoming, h.eta_beyond) {
                        (Some(a), Some(b)) => format!(", index {a} -> {b}"),
                        _ => String::new(),
                    }
                ),
            );
            if let Some(s) = &n.intersection {
                for l in test_lines(s) {
                    line(out, format!("  {l}"));
                }
            }
            line(out, format!("  ambient ka*Od*Ia = {}", rgb(n.ambient)));
            if n.emission != [0.0; 3] {
                line(out, format!("  emission = {}", rgb(n.emission)));
            }
            for l in &n.lights {
                line(
                    out,
                    format!(
                        "  light `{}`{}: {} samples, {} feelers, visible {}; diffuse kd*Od*max(0,N.L) = {}, specular ks*max(0,R.V)^n = {}; sum {}",
                        l.light,
                        l.spot_cone.map_or(String::new(), |c| format!(
                            " (spot: its cone sends {c:.6} of its intensity here)"
                        )),
                        l.samples,
                        l.feelers,
                        rgb(l.visible_fraction),
                        rgb(l.diffuse),
                        rgb(l.specular),
                        rgb(l.contribution)
                    ),
                );
            }
            line(
                out,
                format!(
                    "  kr = {}, kt = {}{}",
                    rgb(n.kr),
                    rgb(n.kt),
                    if n.total_internal_reflection {
                        " (total internal reflection: all of it reflected)"
                    } else {
                        ""
                    }
                ),
            );
        }
    }
    if let Some(r) = &n.reflection {
        line(
            out,
            format!(
                "  reflection: I.N = {:.6}, R = I - 2N(I.N) = {} (angle {:.4} deg)",
                r.i_dot_n,
                rgb(r.r),
                r.theta
            ),
        );
    }
    if let Some(r) = &n.refraction {
        line(
            out,
            format!(
                "  refraction: eta = {}/{} = {:.6}, theta_i = {:.4} deg{}; {}",
                r.eta_i,
                r.eta_t,
                r.eta,
                r.theta_i,
                r.critical_angle
                    .map_or(String::new(), |c| format!(", critical angle {c:.4} deg")),
                match (r.theta_t, r.t) {
                    (Some(theta_t), Some(t)) => {
                        format!("theta_t = {theta_t:.4} deg, T = w + eta*u = {}", rgb(t))
                    }
                    _ => format!(
                        "1 - eta^2(1 - cos^2 theta_i) = {:.6} < 0: total internal reflection",
                        r.radicand
                    ),
                }
            ),
        );
    }
    if !n.rejected.is_empty() {
        line(
            out,
            format!(
                "  also tested: {} objects{}",
                n.rejected.len() + n.rejected_left_out,
                if n.rejected_left_out > 0 {
                    format!(", the {} nearest the ray:", n.rejected.len())
                } else {
                    ":".into()
                }
            ),
        );
        for r in &n.rejected {
            line(
                out,
                format!("    `{}` ({}): {}", r.object, r.shape, r.verdict),
            );
        }
    }
    for why in &n.stopped {
        line(out, format!("  stops: {why}"));
    }
    if let Some(r) = &n.reflected {
        line(
            out,
            format!("  kr * I_reflected = {}:", rgb(n.reflected_term)),
        );
        node(r, indent + 2, out);
    }
    if let Some(t) = &n.refracted {
        line(
            out,
            format!("  kt * I_refracted = {}:", rgb(n.refracted_term)),
        );
        node(t, indent + 2, out);
    }
    line(out, format!("  = {}", rgb(n.radiance)));
}

/// The intersection test of the object hit, as the notes work it.
fn test_lines(s: &IntersectionSteps) -> Vec<String> {
    let mut lines = Vec::new();
    if let Some(p) = &s.plane {
        lines.push(format!(
            "{} test: n = {}, n.d = {:.6} ({}), t = (d - n.O)/(n.d) = {}{}",
            s.shape,
            rgb(p.normal),
            p.n_dot_d,
            p.verdict,
            p.t.map_or("-".into(), |t| format!("{t:.6}")),
            p.point
                .map_or(String::new(), |q| format!(", P = O + tD = {}", rgb(q)))
        ));
    }
    if let Some(p) = &s.polygon {
        let count = |case: &str| p.edges.iter().filter(|e| e.case == case).count();
        lines.push(format!(
            "principal axis {} (the normal's largest component), projected onto {}; \
             hit translated to the origin, test ray along +{}: of {} edges, {} both z positive, \
             {} both z negative, {} both x negative, {} x_int computed ({} > 0); \
             crossings {} ({}): {}",
            p.principal_axis,
            p.projected_onto,
            p.x_axis,
            p.edges.len() + p.edges_left_out,
            count("both z positive"),
            count("both z negative"),
            count("both x negative"),
            count("x_int"),
            p.edges.iter().filter(|e| e.crosses).count(),
            p.crossings,
            p.parity,
            if p.inside { "inside" } else { "outside" }
        ));
    }
    if let Some(q) = &s.sphere {
        lines.push(format!(
            "{} test{}: a = {:.6}, b = {:.6}, c = {:.6}, discriminant b^2 - 4ac = {:.6}; {}",
            s.shape,
            if q.object_space {
                " (unit sphere, object space)"
            } else {
                ""
            },
            q.a,
            q.b,
            q.c,
            q.discriminant,
            match (q.roots, q.taken) {
                (Some([t0, t1]), Some(taken)) => {
                    format!("roots t0 = {t0:.6}, t1 = {t1:.6}; {taken} taken")
                }
                (Some([t0, t1]), None) => format!("roots t0 = {t0:.6}, t1 = {t1:.6}, both behind"),
                _ => "no real roots".into(),
            }
        ));
    }
    if let Some(t) = &s.triangle {
        lines.push(format!(
            "watertight test of triangle {}{}: axes (kx, ky, kz) = ({}, {}, {}); edge functions U, V, W = {} ({}), det = U + V + W = {}, t = {}, barycentrics {}",
            t.triangle,
            if t.object_space { " (mesh space)" } else { "" },
            t.axes[0],
            t.axes[1],
            t.axes[2],
            rgb(t.edge_functions),
            t.signs,
            t.det.map_or("-".into(), |d| format!("{d:.6}")),
            t.t.map_or("-".into(), |t| format!("{t:.6}")),
            t.barycentric.map_or("-".into(), rgb)
        ));
    }
    lines
}
