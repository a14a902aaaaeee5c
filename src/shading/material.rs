//! The coefficients of the Whitted model for one surface.

use super::Texture;

/// How kr and kt are found at a hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Fresnel {
    /// Classic Whitted: the material's kr and kt as given.
    #[default]
    Off,
    /// kr + kt split by the exact dielectric Fresnel reflectance.
    Exact,
    /// kr + kt split by Schlick's approximation.
    Schlick,
}

/// Which specular highlight term the local model uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Highlight {
    /// Phong: max(0, R·V)ⁿ with R the mirror of L.
    #[default]
    Phong,
    /// Blinn-Phong: max(0, N·H)ⁿ with H the half vector of L and V.
    Blinn,
}

/// A Whitted material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Surface colour Od.
    pub texture: Texture,
    /// Ambient coefficient.
    pub ka: f64,
    /// Diffuse coefficient.
    pub kd: f64,
    /// Specular highlight coefficient.
    pub ks: f64,
    /// Phong exponent n.
    pub shininess: f64,
    /// Weight of the reflected ray.
    pub kr: f64,
    /// Weight of the transmitted ray.
    pub kt: f64,
    /// Index of refraction of the inside.
    pub ior: f64,
    /// Fresnel mode.
    pub fresnel: Fresnel,
    /// Highlight model.
    pub highlight: Highlight,
}
