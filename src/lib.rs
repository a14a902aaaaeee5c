//! Prism: an exact Whitted-style ray tracer.
//!
//! A scene file is parsed and validated into a [`Scene`] (`scene`), whose
//! primitives (`geometry`) sit in an [`accel::Aggregate`]; the render loop
//! (`render`) sends camera rays (`camera`) through the Whitted model
//! (`shading`), which samples the `lights` with shadow feelers; the film is
//! written by `image_io`.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod accel;
pub mod camera;
pub mod geometry;
pub mod image_io;
pub mod lights;
pub mod math;
pub mod render;
pub mod scene;
pub mod shading;

pub use render::{RenderObserver, RenderOutput, RenderSettings, render};
pub use scene::{Scene, SceneError};
