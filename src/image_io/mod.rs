//! Writing the film: PNG and PPM as 8-bit sRGB (clamped), EXR and HDR as
//! linear float radiance (unclamped), always through a temporary file that
//! is renamed into place, so a failed render never leaves a truncated image
//! and never destroys the previous one.
//!
//! Every format starts from the radiance rounded to f32, the precision an
//! EXR part holds, so an image merged from EXR parts equals, byte for byte,
//! the one rendered whole, in any format.

pub mod exr;
pub mod merge;

pub use exr::{Part, Provenance, read_part};
pub use merge::{MergeError, merge_parts, merge_parts_with, missing_regions};

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use image::codecs::pnm::{PnmEncoder, PnmSubtype, SampleEncoding};
use image::{DynamicImage, ImageFormat, Rgb32FImage, RgbImage};
use thiserror::Error;

use crate::math::transcendental;
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
    /// The output cannot be written where it is asked for (checked before
    /// rendering).
    #[error("{path}: {reason}")]
    Unwritable {
        /// The output path.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// A signal stopped the write; the temporary file is gone and any old
    /// file at the path is untouched.
    #[error("{path}: interrupted while writing; the previous file (if any) is untouched")]
    Interrupted {
        /// The output path.
        path: PathBuf,
    },
    /// The encoder failed.
    #[error("{path}: {message}")]
    Encode {
        /// The output path.
        path: PathBuf,
        /// The encoder's message.
        message: String,
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
        1.055 * transcendental::pow(v, 1.0 / 2.4) - 0.055
    }
}

/// A linear value clamped to [0, 1], sRGB-encoded and rounded to 8 bits.
pub fn to_srgb8(v: f64) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (linear_to_srgb(v) * 255.0).round() as u8
}

/// [`to_srgb8`] of an f32 (what films hold once written), by table: the
/// encoding only steps up at 255 values, found once by bisection with
/// `to_srgb8` itself, and the answer is how many of them `v` reaches.
/// That is `to_srgb8`'s answer to the bit because `to_srgb8` never
/// decreases from one f32 to the next: the true x^(1/2.4) grows by about
/// 2²⁸ units in the last place of f64 between neighbouring f32, far more
/// than libm's pow is ever off by (under one unit), and the steps after it
/// (scale, shift, round) are monotone. A test checks every f32 near each
/// step and a sweep of the rest. A fifth of the cost of pow per value,
/// which was 3 % of a render's CPU time.
pub fn srgb8_of_f32(v: f32) -> u8 {
    static STEPS: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    let steps = STEPS.get_or_init(|| {
        // Step k − 1: the least f32 in (0, 1] that encodes to k or more.
        std::array::from_fn(|i| {
            let k = i as u8 + 1;
            let (mut below, mut at) = (0u32, 1.0f32.to_bits());
            while at - below > 1 {
                let mid = below + (at - below) / 2;
                if to_srgb8(f64::from(f32::from_bits(mid))) >= k {
                    at = mid;
                } else {
                    below = mid;
                }
            }
            f32::from_bits(at)
        })
    });
    // Branch-free binary search: how many steps are at or below v (none
    // for NaN, whose comparisons fail, as `to_srgb8` gives it 0).
    let mut count = 0usize;
    for half in [128, 64, 32, 16, 8, 4, 2, 1] {
        if count + half <= 255 && steps[count + half - 1] <= v {
            count += half;
        }
    }
    count as u8
}

/// A linear value as a finite f32: radiance beyond f32's range saturates
/// at its largest value rather than becoming infinity (NaN, which no valid
/// scene produces, is written as 0, as in the 8-bit formats).
pub fn to_f32(v: f64) -> f32 {
    if v.is_nan() {
        0.0
    } else {
        v.clamp(-f64::from(f32::MAX), f64::from(f32::MAX)) as f32
    }
}

/// Applies an exposure of `ev` stops for 8-bit output: each value as an
/// EXR part stores it (rounded to f32), times 2^`ev`. Rounding first makes
/// a PNG merged from EXR parts equal, byte for byte, to the one rendered
/// whole.
pub fn expose(film: &mut Film, ev: f64) {
    if ev != 0.0 {
        let k = crate::settings::exposure_scale(ev);
        film.map(|v| f64::from(to_f32(v)) * k);
    }
}

/// The film's region as an 8-bit or float image (not EXR, which
/// [`exr::write`] writes with its data window).
fn to_image(film: &Film, format: OutputFormat) -> DynamicImage {
    let (w, h) = (film.region().width(), film.region().height());
    let srgb8 = |v: f64| srgb8_of_f32(to_f32(v));
    match format {
        OutputFormat::Png | OutputFormat::Ppm => {
            let data = film
                .pixels()
                .iter()
                .flat_map(|p| [srgb8(p.x), srgb8(p.y), srgb8(p.z)])
                .collect();
            DynamicImage::ImageRgb8(
                RgbImage::from_raw(w, h, data).expect("buffer matches the film size"),
            )
        }
        OutputFormat::Exr | OutputFormat::Hdr => {
            let data = film
                .pixels()
                .iter()
                .flat_map(|p| [to_f32(p.x), to_f32(p.y), to_f32(p.z)])
                .collect();
            DynamicImage::ImageRgb32F(
                Rgb32FImage::from_raw(w, h, data).expect("buffer matches the film size"),
            )
        }
    }
}

/// Longest file name most file systems take (NAME_MAX on Linux).
const MAX_NAME_BYTES: usize = 255;

/// The folder an output goes in.
fn output_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Checks, before a render starts, that `path` can be written: a known
/// extension, a file name the file system takes, an existing folder in which
/// a file can be created (one is created and removed again), not a folder.
/// Messages name `path`, never a temporary name.
pub fn check_writable(path: &Path) -> Result<OutputFormat, ImageWriteError> {
    let format = OutputFormat::from_path(path)?;
    let unwritable = |reason: String| ImageWriteError::Unwritable {
        path: path.to_path_buf(),
        reason,
    };
    let name_len = path.file_name().map_or(0, |n| n.len());
    if name_len > MAX_NAME_BYTES {
        return Err(unwritable(format!(
            "the file name is {name_len} bytes; at most {MAX_NAME_BYTES} are allowed"
        )));
    }
    let dir = output_dir(path);
    if !dir.is_dir() {
        return Err(unwritable(format!(
            "the folder {} does not exist",
            dir.display()
        )));
    }
    if path.is_dir() {
        return Err(unwritable(
            "is a directory; expected an image file name".into(),
        ));
    }
    // An unnamed file (O_TMPFILE where the system has it): a signal that
    // kills the process during the probe leaves nothing behind.
    tempfile::tempfile_in(dir)
        .map_err(|e| unwritable(format!("cannot create files in {}: {e}", dir.display())))?;
    Ok(format)
}

/// A writer that fails once `stop` is set, so that a signal during a long
/// write ends it at the next buffer and the temporary file is removed.
struct Stoppable<'a, W> {
    inner: W,
    stop: &'a AtomicBool,
}

impl<W: Write> Write for Stoppable<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.stop.load(Ordering::SeqCst) {
            // Not ErrorKind::Interrupted: write_all retries that for ever.
            return Err(std::io::Error::other("stopped by a signal"));
        }
        self.inner.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<W: std::io::Seek> std::io::Seek for Stoppable<'_, W> {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// Writes `film` to `path` in the format its extension names, atomically:
/// the image is written to a temporary file beside `path` and renamed over
/// it only once complete.
pub fn write_film(film: &Film, path: &Path) -> Result<(), ImageWriteError> {
    write_film_unless(film, path, None, &AtomicBool::new(false))
}

/// [`write_film`] with the pixels' provenance (stored in EXR files), and
/// abandoned as soon as `stop` is set (by a signal handler): then the
/// temporary file is removed, any old file at `path` is untouched, and the
/// result is [`ImageWriteError::Interrupted`]. A film over a region is
/// written as that region (EXR: as its data window in the whole frame).
pub fn write_film_unless(
    film: &Film,
    path: &Path,
    provenance: Option<&Provenance>,
    stop: &AtomicBool,
) -> Result<(), ImageWriteError> {
    let format = OutputFormat::from_path(path)?;
    let io_error = |source| ImageWriteError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = output_dir(path);
    let mut builder = tempfile::Builder::new();
    builder.prefix(".prism-").suffix(".part");
    // Temporary files are private (0600) by default; the image should get
    // the permissions any new file gets (0666 less the umask).
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let temp = builder.tempfile_in(dir).map_err(io_error)?;
    let interrupted = || ImageWriteError::Interrupted {
        path: path.to_path_buf(),
    };
    {
        let mut writer = BufWriter::new(Stoppable {
            inner: temp.as_file(),
            stop,
        });
        let encoded = match format {
            // Binary PPM (P6), which every viewer reads; the image crate's
            // default for .ppm is PAM (P7).
            OutputFormat::Ppm => to_image(film, format)
                .write_with_encoder(
                    PnmEncoder::new(&mut writer)
                        .with_subtype(PnmSubtype::Pixmap(SampleEncoding::Binary)),
                )
                .map_err(|e| e.to_string()),
            OutputFormat::Png => to_image(film, format)
                .write_to(&mut writer, ImageFormat::Png)
                .map_err(|e| e.to_string()),
            OutputFormat::Exr => exr::write(film, provenance, &mut writer),
            OutputFormat::Hdr => to_image(film, format)
                .write_to(&mut writer, ImageFormat::Hdr)
                .map_err(|e| e.to_string()),
        };
        if stop.load(Ordering::SeqCst) {
            return Err(interrupted());
        }
        encoded.map_err(|message| ImageWriteError::Encode {
            path: path.to_path_buf(),
            message,
        })?;
        writer.flush().map_err(io_error)?;
    }
    temp.as_file().sync_all().map_err(io_error)?;
    if stop.load(Ordering::SeqCst) {
        return Err(interrupted());
    }
    temp.persist(path).map_err(|e| io_error(e.error))?;
    Ok(())
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // hand-worked values use the platform's functions
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

    /// The table answers as `to_srgb8` does: on every f32 within 4,096
    /// of each step, on a sweep of the rest of [0, 1], and out of range.
    #[test]
    fn srgb8_of_f32_is_to_srgb8() {
        let check = |v: f32| {
            assert_eq!(srgb8_of_f32(v), to_srgb8(f64::from(v)), "{v:e}");
        };
        let one = 1.0f32.to_bits();
        let mut steps = 0;
        for bits in (0..one).step_by(997) {
            let v = f32::from_bits(bits);
            check(v);
            if to_srgb8(f64::from(v)) != to_srgb8(f64::from(f32::from_bits(bits + 997))) {
                steps += 1;
                for near in bits.saturating_sub(4096)..(bits + 997 + 4096).min(one + 1) {
                    check(f32::from_bits(near));
                }
            }
        }
        assert!(steps >= 200, "{steps}");
        for v in [-1.0, -0.0, 0.0, 1.0, 1.5, f32::MAX, f32::INFINITY, f32::NAN] {
            check(v);
        }
    }

    /// Every f32 in [0, 1]: a billion pow calls, so run by hand
    /// (`cargo test --release -- --ignored srgb8_of_every_f32`).
    #[test]
    #[ignore]
    fn srgb8_of_every_f32() {
        for bits in 0..=1.0f32.to_bits() {
            let v = f32::from_bits(bits);
            assert_eq!(srgb8_of_f32(v), to_srgb8(f64::from(v)), "{v:e}");
        }
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
    fn ppm_is_binary_p6() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.ppm");
        write_film(&Film::new(2, 1), &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.starts_with(b"P6"), "{:?}", &bytes[..8]);
        assert!(bytes.ends_with(&[0; 6]));
    }

    #[test]
    fn a_stopped_write_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        std::fs::write(&path, b"old").unwrap();
        let stop = AtomicBool::new(true);
        assert!(matches!(
            write_film_unless(&Film::new(64, 64), &path, None, &stop),
            Err(ImageWriteError::Interrupted { .. })
        ));
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn unwritable_outputs_are_found_before_rendering() {
        let dir = tempfile::tempdir().unwrap();
        let long = dir.path().join(format!("{}.png", "x".repeat(300)));
        let e = check_writable(&long).unwrap_err().to_string();
        assert!(e.contains("at most 255"), "{e}");
        let missing = dir.path().join("no/such/a.png");
        assert!(
            check_writable(&missing)
                .unwrap_err()
                .to_string()
                .contains("does not exist")
        );
        assert!(check_writable(dir.path()).is_err());
        assert_eq!(
            check_writable(&dir.path().join("a.exr")).unwrap(),
            OutputFormat::Exr
        );
        // The probe leaves nothing behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        assert_eq!(to_f32(1e300), f32::MAX);
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
