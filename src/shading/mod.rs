//! The Whitted illumination model and what it needs: optics (reflect,
//! refract, Fresnel), glossy lobes, materials and textures.

pub mod glossy;
pub mod material;
pub mod optics;
pub mod texture;
pub mod whitted;

pub use material::{Fresnel, Highlight, Material};
pub use texture::Texture;
