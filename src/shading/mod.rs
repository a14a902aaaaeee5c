//! The Whitted illumination model and what it needs: optics (reflect,
//! refract, Fresnel), materials and textures.

pub mod material;
pub mod optics;
pub mod texture;
pub mod whitted;

pub use material::{Fresnel, Highlight, Material};
pub use texture::Texture;
