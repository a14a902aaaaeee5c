//! Writing the film: PNG and PPM as 8-bit sRGB (clamped), EXR and HDR as
//! linear float radiance (unclamped), always through a temporary file that
//! is renamed into place, so a failed render never leaves a truncated image
//! and never destroys the previous one.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageFormat, Rgb32FImage, RgbImage};
use thiserror::Error;

use crate::render::Film;

/// The image formats Prism writes, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// `.png`: 8-bit sRGB.
    Png,
    /// `.ppm`: 8-bit sRGB, binary PPM.
    Ppm,
    /// `.exr`: OpenEXR, linear float32.
    Exr,
    /// `.hdr`: Radiance RGBE, linear.
    Hdr,
}

/// Why an image could not be written.
#[derive(Debug, Error)]
pub enum ImageWriteError {
    /// The extension names no supported format.
    #[error("{path}: unknown image format; use .png, .ppm, .exr or .hdr")]
    UnknownFormat {
        /// The output path.
        path: PathBuf,
    },
    /// Creating, writing or renaming the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The output path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The encoder failed.
    #[error("{path}: {source}")]
    Encode {
        /// The output path.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
}

impl OutputFormat {
    /// The format for `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self, ImageWriteError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(OutputFormat::Png),
            Some("ppm") => Ok(OutputFormat::Ppm),
            Some("exr") => Ok(OutputFormat::Exr),
            Some("hdr") => Ok(OutputFormat::Hdr),
            _ => Err(ImageWriteError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
pub fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// A linear value clamped to [0, 1], sRGB-encoded and rounded to 8 bits.
pub fn to_srgb8(v: f64) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (linear_to_srgb(v) * 255.0).round() as u8
}

fn to_image(film: &Film, format: OutputFormat) -> DynamicImage {
    let (w, h) = (film.width(), film.height());
    match format {
        OutputFormat::Png | OutputFormat::Ppm => {
            let data = film
                .pixels()
                .iter()
                .flat_map(|p| [to_srgb8(p.x), to_srgb8(p.y), to_srgb8(p.z)])
                .collect();
            DynamicImage::ImageRgb8(
                RgbImage::from_raw(w, h, data).expect("buffer matches the film size"),
            )
        }
        OutputFormat::Exr | OutputFormat::Hdr => {
            let data = film
                .pixels()
                .iter()
                .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
                .collect();
            DynamicImage::ImageRgb32F(
                Rgb32FImage::from_raw(w, h, data).expect("buffer matches the film size"),
            )
        }
    }
}

/// Writes `film` to `path` in the format its extension names, atomically:
/// the image is written to a temporary file beside `path` and renamed over
/// it only once complete.
pub fn write_film(film: &Film, path: &Path) -> Result<(), ImageWriteError> {
    let format = OutputFormat::from_path(path)?;
    let io_error = |source| ImageWriteError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".prism-").suffix(".part");
    // Temporary files are private (0600) by default; the image should get
    // the permissions any new file gets (0666 less the umask).
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let temp = builder.tempfile_in(dir).map_err(io_error)?;
    let image_format = match format {
        OutputFormat::Png => ImageFormat::Png,
        OutputFormat::Ppm => ImageFormat::Pnm,
        OutputFormat::Exr => ImageFormat::OpenExr,
        OutputFormat::Hdr => ImageFormat::Hdr,
    };
    {
        let mut writer = BufWriter::new(temp.as_file());
        to_image(film, format)
            .write_to(&mut writer, image_format)
            .map_err(|source| ImageWriteError::Encode {
                path: path.to_path_buf(),
                source,
            })?;
        writer.flush().map_err(io_error)?;
    }
    temp.as_file().sync_all().map_err(io_error)?;
    temp.persist(path).map_err(|e| io_error(e.error))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn srgb_encoding_known_values() {
        assert_eq!(to_srgb8(0.0), 0);
        assert_eq!(to_srgb8(1.0), 255);
        assert_eq!(to_srgb8(7.0), 255, "clamped");
        assert_eq!(to_srgb8(-1.0), 0);
        assert_eq!(to_srgb8(f64::NAN), 0);
        // Linear 0.5 is sRGB 0.7354: 188 of 255.
        assert_eq!(to_srgb8(0.5), 188);
        // Continuity at the knee.
        let k = 0.003_130_8f64;
        assert!((12.92 * k - (1.055 * k.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
    }

    #[test]
    fn every_format_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let mut film = Film::new(3, 2);
        film.set(2, 1, DVec3::new(4.0, 0.5, 0.25));
        for ext in ["png", "ppm", "exr", "hdr"] {
            let path = dir.path().join(format!("out.{ext}"));
            write_film(&film, &path).unwrap();
            let img = image::open(&path).unwrap();
            assert_eq!((img.width(), img.height()), (3, 2));
            let px = img.to_rgb32f().get_pixel(2, 1).0;
            if ext == "exr" || ext == "hdr" {
                assert!(
                    (px[0] - 4.0).abs() < 0.05,
                    "{ext}: unclamped radiance, got {px:?}"
                );
            } else {
                assert_eq!(img.to_rgb8().get_pixel(2, 1).0, [255, 188, 137]);
            }
        }
        // Nothing but the four outputs: the temporaries are gone.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 4);
        // The same permissions as any new file (not the private 0600 of a
        // temporary file).
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = |name: &str| {
                std::fs::metadata(dir.path().join(name))
                    .unwrap()
                    .permissions()
                    .mode()
            };
            std::fs::write(dir.path().join("plain"), b"").unwrap();
            assert_eq!(mode("out.png"), mode("plain"));
        }
    }

    #[test]
    fn unknown_extension_is_refused_before_anything_is_written() {
        assert!(matches!(
            OutputFormat::from_path(Path::new("x.jpg")),
            Err(ImageWriteError::UnknownFormat { .. })
        ));
        assert!(OutputFormat::from_path(Path::new("x.PNG")).is_ok());
    }
}
