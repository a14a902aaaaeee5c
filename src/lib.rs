//! Prism: an exact Whitted-style ray tracer.
//!
//! A scene file is parsed and validated into a [`Scene`] (`scene`), whose
//! primitives (`geometry`) sit in an [`accel::Aggregate`]; the render loop
//! (`render`) sends camera rays (`camera`) through the Whitted model
//! (`shading`), which samples the `lights` with shadow feelers; the film is
//! written by `image_io`.
//!
//! ```
//! use prism::{RenderSettings, Scene, render};
//!
//! let scene = Scene::from_toml(prism::scene::DEFAULT_SCENE, "demo").unwrap();
//! let settings = RenderSettings { width: 32, height: 24, spp: 1, ..scene.settings };
//! let output = render(&scene, &settings, &()).unwrap();
//! assert_eq!(output.film.width(), 32);
//! assert!(output.stats.camera == 32 * 24);
//! // prism::image_io::write_film(&output.film, "demo.png".as_ref()) writes it.
//! ```

// Denied everywhere; only accel/simd/avx2.rs (the AVX2 intrinsics) and
// huge_pages.rs (one `madvise`) allow it.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod accel;
pub mod camera;
pub mod geometry;
pub mod huge_pages;
pub mod image_io;
pub mod lights;
pub mod limits;
pub mod math;
pub mod query;
pub mod render;
pub mod scene;
pub mod settings;
pub mod shading;
pub mod stats;
pub mod text;

pub use render::{RenderObserver, RenderOutput, render};
pub use scene::{Scene, SceneError};
pub use settings::RenderSettings;
pub use stats::RayStats;
