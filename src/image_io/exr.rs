//! OpenEXR through the `exr` crate: linear f32 RGB, the film's region as
//! the data window inside the whole frame's display window, and one text
//! attribute, `prism`, saying what the pixels were made from. Parts of a
//! frame rendered apart are read back, checked against each other and
//! merged from these files.

use std::io::{Seek, Write};
use std::path::Path;

use exr::prelude::{
    AttributeValue, Encoding, Image, IntegerBounds, Layer, LayerAttributes, SpecificChannels, Text,
    Vec2, WritableImage, read_first_rgba_layer_from_file,
};
use glam::DVec3;
use sha2::{Digest, Sha256};

use super::to_f32;
use crate::limits;
use crate::render::{Film, Region};

/// Name of the EXR attribute holding a [`Provenance`].
const ATTRIBUTE: &str = "prism";
/// The attribute's last line: the SHA-256 of the lines before it and of
/// the pixels as stored, so a damaged or doctored part is refused.
const DIGEST_KEY: &str = "pixels_sha256=";
/// The most a deflate stream (EXR's ZIP compression) can expand: 1032 to 1.
/// A header promising more pixels than its file can hold is lying.
const MAX_ZIP_RATIO: u64 = 1032;
/// Bytes of one stored pixel: three f32.
const STORED_PIXEL_BYTES: u64 = 12;

/// What a render's pixels were made from: two parts whose provenance is
/// equal belong to the same image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Provenance {
    /// SHA-256 over the scene text and every file it read
    /// (`Inventory::content_hash`).
    pub scene_hash: String,
    /// The model camera chosen by name (`--camera`), in ASCII: every
    /// other character escaped as `\u{…}` (one name, one form; an EXR text
    /// attribute holds Latin-1 only); empty for the scene's own choice.
    pub camera: String,
    /// The settings that change pixels, in canonical form
    /// (`RenderSettings::pixel_key`, with ` aov=NAME` for a debug view).
    pub settings: String,
    /// Seed of the random streams.
    pub seed: u64,
    /// Animation frame.
    pub frame: u32,
}

impl Provenance {
    /// What `settings` make of `scene`: its content hash, the camera
    /// chosen by name, the pixel settings, seed and frame.
    pub fn of(scene: &crate::Scene, settings: &crate::RenderSettings) -> Provenance {
        Provenance {
            scene_hash: scene.inventory.content_hash.clone(),
            camera: scene
                .inventory
                .camera
                .as_deref()
                .map_or(String::new(), |c| c.escape_default().to_string()),
            settings: settings.pixel_key(),
            seed: settings.seed,
            frame: settings.frame,
        }
    }

    /// The fields as (name, value), in the order they are stored; the
    /// camera only when one was chosen by name, so the keys of every other
    /// render (and their parts and checkpoints) stay as they were.
    pub fn fields(&self) -> Vec<(&'static str, String)> {
        let mut fields = vec![("scene_sha256", self.scene_hash.clone())];
        if !self.camera.is_empty() {
            fields.push(("camera", self.camera.clone()));
        }
        fields.extend([
            ("settings", self.settings.clone()),
            ("seed", self.seed.to_string()),
            ("frame", self.frame.to_string()),
        ]);
        fields
    }

    /// Every option that changes a pixel as (name, value), the settings
    /// line taken apart (`size`, `spp`, `max_depth`, `min_weight`,
    /// `exposure`, `aov`): what merge and resume compare, and what their
    /// refusals name. An option a key does not carry has its default.
    pub fn options(&self) -> Vec<(String, String)> {
        let mut options = vec![
            ("scene_sha256".to_string(), self.scene_hash.clone()),
            (
                "camera".to_string(),
                if self.camera.is_empty() {
                    "the scene's".to_string()
                } else {
                    self.camera.clone()
                },
            ),
        ];
        let mut words = self.settings.split(' ').filter(|w| !w.is_empty());
        if let Some(size) = words.next() {
            options.push(("size".into(), size.to_string()));
        }
        let mut rest: Vec<(String, String)> = words
            .map(|w| match w.split_once('=') {
                Some((k, v)) => (k.to_string(), v.to_string()),
                None => (w.to_string(), String::new()),
            })
            .collect();
        // Options older keys (and keys of the defaults) leave out.
        for (name, default) in [("exposure", "0"), ("aov", "none (the picture)")] {
            if !rest.iter().any(|(k, _)| k == name) {
                rest.push((name.to_string(), default.to_string()));
            }
        }
        options.extend(rest);
        options.push(("seed".into(), self.seed.to_string()));
        options.push(("frame".into(), self.frame.to_string()));
        options
    }

    /// The first option in which `other` differs, as (name, ours, theirs).
    pub fn difference(&self, other: &Provenance) -> Option<(String, String, String)> {
        let theirs = other.options();
        let ours = self.options();
        let value = |list: &[(String, String)], name: &str| {
            list.iter()
                .find(|(k, _)| k == name)
                .map_or_else(|| "none".to_string(), |(_, v)| v.clone())
        };
        ours.iter()
            .map(|(k, _)| k)
            .chain(theirs.iter().map(|(k, _)| k))
            .find(|k| value(&ours, k) != value(&theirs, k))
            .map(|k| (k.clone(), value(&ours, k), value(&theirs, k)))
    }

    /// The fields and `region`, one `name=value` line each: the EXR
    /// attribute, and the key of a checkpoint.
    pub fn to_text(&self, region: Region) -> String {
        let mut text: String = self
            .fields()
            .iter()
            .map(|(k, v)| format!("{k}={v}\n"))
            .collect();
        text.push_str(&format!("region={region}\n"));
        text
    }

    /// Why the render keyed `theirs` (a [`to_text`](Self::to_text)) is not
    /// the render keyed `ours`, naming the option: `its spp is `8`, this
    /// render's `4``; `None` when they are the same render.
    pub fn key_difference(ours: &str, theirs: &str) -> Option<String> {
        if ours == theirs {
            return None;
        }
        if let (Ok((a, ra)), Ok((b, rb))) = (Self::from_text(ours), Self::from_text(theirs)) {
            if let Some((name, ours, theirs)) = a.difference(&b) {
                return Some(format!("its {name} is `{theirs}`, this render's `{ours}`"));
            }
            if ra != rb {
                return Some(format!("its region is `{rb}`, this render's `{ra}`"));
            }
        }
        // Not a key of this version: the first line that differs.
        let (a, b) = ours
            .lines()
            .zip(theirs.lines().chain(std::iter::repeat("")))
            .find(|(a, b)| a != b)
            .unwrap_or(("", ""));
        Some(format!("it has `{b}`, this render `{a}`"))
    }

    fn from_text(text: &str) -> Result<(Provenance, Region), String> {
        let get = |key: &str| {
            text.lines()
                .find_map(|l| l.strip_prefix(key).and_then(|r| r.strip_prefix('=')))
                .ok_or_else(|| format!("its `prism` attribute has no `{key}`"))
        };
        let number = |key: &str| -> Result<u64, String> {
            get(key)?
                .parse()
                .map_err(|_| format!("its `prism` attribute's `{key}` is not a number"))
        };
        let region: Vec<u32> = get("region")?
            .split(',')
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| "its `prism` attribute's `region` is not X0,X1,Y0,Y1".to_string())?;
        let [x0, x1, y0, y1] = region[..] else {
            return Err("its `prism` attribute's `region` is not X0,X1,Y0,Y1".into());
        };
        Ok((
            Provenance {
                scene_hash: get("scene_sha256")?.to_string(),
                // Parts written before cameras were recorded: the scene's.
                camera: get("camera").unwrap_or_default().to_string(),
                settings: get("settings")?.to_string(),
                seed: number("seed")?,
                frame: u32::try_from(number("frame")?)
                    .map_err(|_| "its frame number is too large".to_string())?,
            },
            Region { x0, x1, y0, y1 },
        ))
    }
}

/// Writes `film` as EXR to `out`: the data window is the film's region,
/// the display window the whole frame. The bytes depend only on the pixels
/// and the provenance (no time stamps, attributes in a fixed order), so two
/// renders of the same image give the same file.
pub fn write(
    film: &Film,
    provenance: Option<&Provenance>,
    out: impl Write + Seek,
) -> Result<(), String> {
    let region = film.region();
    let width = region.width() as usize;
    let pixels = film.pixels();
    let mut attributes = LayerAttributes {
        layer_position: Vec2(region.x0 as i32, region.y0 as i32),
        ..LayerAttributes::default()
    };
    if let Some(p) = provenance {
        // One attribute: the crate keeps custom attributes in a hash map,
        // whose order would change from run to run.
        let mut text = p.to_text(region);
        let digest = pixel_digest(&text, pixels.iter().copied());
        text.push_str(&format!("{DIGEST_KEY}{digest}\n"));
        attributes.other.insert(
            Text::from(ATTRIBUTE),
            AttributeValue::Text(Text::from(text.as_str())),
        );
    }
    let layer = Layer::new(
        (width, region.height() as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        SpecificChannels::rgb(|at: Vec2<usize>| {
            let p = pixels[at.y() * width + at.x()];
            (to_f32(p.x), to_f32(p.y), to_f32(p.z))
        }),
    );
    let mut image = Image::from_layer(layer);
    image.attributes.display_window =
        IntegerBounds::new((0, 0), (film.width() as usize, film.height() as usize));
    image
        .write()
        .non_parallel()
        .to_buffered(out)
        .map_err(|e| e.to_string())
}

/// SHA-256, in hex, of `text` and then the pixels as an EXR part stores
/// them (f32 RGB, little-endian, row by row).
fn pixel_digest(text: &str, pixels: impl Iterator<Item = DVec3>) -> String {
    let mut hash = Sha256::new();
    hash.update(text.as_bytes());
    for p in pixels {
        for c in [p.x, p.y, p.z] {
            hash.update(to_f32(c).to_le_bytes());
        }
    }
    hash.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// A part read back: its pixels (over its region of the frame) and what
/// they were made from.
pub struct Part {
    /// The pixels, as a film over the part's region.
    pub film: Film,
    /// What they were made from.
    pub provenance: Provenance,
}

/// Reads an EXR written by [`write()`] with a provenance. Messages say what
/// is wrong without the path (the caller names the file). Before any pixel
/// is allocated, the header's sizes are checked against the file's length
/// (no more pixels than its compressed data can hold) and the memory is
/// reserved fallibly; after decoding, the pixels must match the digest the
/// writer stored and, for a picture, be finite and non-negative.
pub fn read_part(path: &Path) -> Result<Part, String> {
    let file_meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if !file_meta.is_file() {
        // A FIFO would block the decoder's open, a device never end.
        return Err(
            "not a regular file (a device, FIFO, socket or folder); expected an EXR part".into(),
        );
    }
    let file_len = file_meta.len();
    // The decoder is not ours: a file it cannot handle must be an error,
    // not a crash of the merge.
    let meta = std::panic::catch_unwind(|| exr::meta::MetaData::read_from_file(path, false))
        .map_err(|_| "the OpenEXR decoder failed on its header".to_string())?
        .map_err(|e| e.to_string())?;
    let [header] = &meta.headers[..] else {
        return Err("not a single-part OpenEXR image written by prism".into());
    };
    let text = match header.own_attributes.other.get(&Text::from(ATTRIBUTE)) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        _ => {
            return Err(
                "it has no `prism` attribute: not a region written by `prism render`".into(),
            );
        }
    };
    let (body, stored_digest) = split_digest(&text)?;
    let (provenance, region) = Provenance::from_text(body)?;
    if header.compression != Encoding::SMALL_LOSSLESS.compression {
        return Err(format!(
            "its compression is {:?}; prism writes ZIP (16 lines): not a part written by prism",
            header.compression
        ));
    }
    let display = header.shared_attributes.display_window;
    let data = header.data_window();
    let (width, height) = (display.size.width(), display.size.height());
    let sane = display.position == Vec2(0, 0)
        && width as u64 <= u64::from(limits::MAX_IMAGE_SIDE)
        && height as u64 <= u64::from(limits::MAX_IMAGE_SIDE)
        && data.position == Vec2(region.x0 as i32, region.y0 as i32)
        && data.size == Vec2(region.width() as usize, region.height() as usize)
        && region.area() > 0
        // No more pixels than a render may have: the pixels are allocated
        // before the file's data is read.
        && region.area() <= limits::MAX_PIXELS
        && Region::full(width as u32, height as u32).contains(&region);
    if !sane {
        return Err(format!(
            "its data window ({:?} + {:?}) and display window disagree with its region {region}",
            data.position, data.size
        ));
    }
    if region.area() * STORED_PIXEL_BYTES > file_len.saturating_mul(MAX_ZIP_RATIO) {
        return Err(format!(
            "its header promises {}x{} pixels, more than its {file_len} bytes can hold",
            region.width(),
            region.height()
        ));
    }
    let (width, height) = (width as u32, height as u32);
    let row = region.width() as usize;
    let area = region.area() as usize;
    let mut buffer: Vec<DVec3> = Vec::new();
    buffer.try_reserve_exact(area).map_err(|_| {
        format!(
            "not enough memory for its {}x{} pixels",
            region.width(),
            region.height()
        )
    })?;
    buffer.resize(area, DVec3::ZERO);
    let buffer = std::sync::Mutex::new(Some(buffer));
    let pixels = std::panic::catch_unwind(move || {
        read_first_rgba_layer_from_file(
            path,
            move |size, _| {
                let reserved = buffer.lock().ok().and_then(|mut b| b.take());
                reserved
                    .filter(|b| b.len() == size.area())
                    .unwrap_or_else(|| vec![DVec3::ZERO; size.area()])
            },
            move |pixels: &mut Vec<DVec3>, at, (r, g, b, _a): (f32, f32, f32, f32)| {
                pixels[at.y() * row + at.x()] = DVec3::new(r.into(), g.into(), b.into());
            },
        )
    })
    .map_err(|_| "the OpenEXR decoder failed on it".to_string())?
    .map_err(|e| e.to_string())?
    .layer_data
    .channel_data
    .pixels;
    if pixel_digest(body, pixels.iter().copied()) != stored_digest {
        return Err(
            "its pixels do not match the digest stored with them: the file is damaged".into(),
        );
    }
    // Debug views hold other quantities (normals are negative, a miss is
    // infinitely deep); a picture holds radiance.
    if !provenance.settings.contains(" aov=")
        && let Some(i) = pixels
            .iter()
            .position(|p| !p.is_finite() || p.min_element() < 0.0)
    {
        let (x, y) = (region.x0 + (i % row) as u32, region.y0 + (i / row) as u32);
        return Err(format!(
            "its pixel ({x}, {y}) holds {:?}: radiance is finite and not negative",
            pixels[i].to_array()
        ));
    }
    let mut film = Film::window(width, height, region);
    film.paste(region, &pixels);
    Ok(Part { film, provenance })
}

/// The attribute text split into the lines the digest covers and the
/// digest (hex), which must be its last line.
fn split_digest(text: &str) -> Result<(&str, &str), String> {
    let missing = || {
        "its `prism` attribute carries no pixel digest: not written by this version of \
         prism; render the part again"
            .to_string()
    };
    let (body, last) = match text.rsplit_once(DIGEST_KEY) {
        Some((body, last)) if body.is_empty() || body.ends_with('\n') => (body, last),
        _ => return Err(missing()),
    };
    let digest = last.strip_suffix('\n').unwrap_or(last);
    if digest.len() != 64 || !digest.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(missing());
    }
    Ok((body, digest))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn provenance(camera: &str, settings: &str) -> Provenance {
        Provenance {
            scene_hash: "ab".into(),
            camera: camera.into(),
            settings: settings.into(),
            seed: 1,
            frame: 0,
        }
    }

    #[test]
    fn a_difference_names_the_option_not_the_line() {
        let a = provenance("", "64x48 spp=4 max_depth=8 min_weight=0.001");
        let region = Region::full(64, 48);
        let diff = |b: &Provenance| a.difference(b).map(|d| d.0);
        assert_eq!(diff(&a.clone()), None);
        assert_eq!(
            diff(&provenance("cam", &a.settings)).as_deref(),
            Some("camera")
        );
        let spp = provenance("", "64x48 spp=8 max_depth=8 min_weight=0.001");
        assert_eq!(diff(&spp).as_deref(), Some("spp"));
        let size = provenance("", "64x40 spp=4 max_depth=8 min_weight=0.001");
        assert_eq!(diff(&size).as_deref(), Some("size"));
        // An option one key leaves out has its default in the other.
        let exposed = provenance("", "64x48 spp=4 max_depth=8 min_weight=0.001 exposure=2");
        assert_eq!(
            a.difference(&exposed),
            Some(("exposure".into(), "0".into(), "2".into()))
        );
        let aov = provenance("", "64x48 spp=4 max_depth=8 min_weight=0.001 aov=normal");
        assert_eq!(diff(&aov).as_deref(), Some("aov"));
        // Checkpoint keys: the option, then the region.
        let key = a.to_text(region);
        assert_eq!(Provenance::key_difference(&key, &key), None);
        let other = Provenance::key_difference(&key, &spp.to_text(region)).unwrap();
        assert!(
            other.contains("its spp is `8`, this render's `4`"),
            "{other}"
        );
        let moved = Provenance::key_difference(&key, &a.to_text(Region::full(64, 40))).unwrap();
        assert!(moved.starts_with("its region is"), "{moved}");
    }

    #[test]
    fn keys_without_a_camera_are_as_they_were_and_names_stay_apart() {
        let a = provenance("", "64x48 spp=4 max_depth=8 min_weight=0.001");
        let text = a.to_text(Region::full(64, 48));
        assert!(!text.contains("camera"), "{text}");
        assert_eq!(Provenance::from_text(&text).unwrap().0, a);
        // Any name, one ASCII form: a control character and its written-out
        // escape stay apart, and CJK is Latin-1-safe for the EXR attribute.
        let forms: Vec<String> = ["a\u{1b}", "a\\u{1b}", "相机"]
            .iter()
            .map(|n| n.escape_default().to_string())
            .collect();
        assert_ne!(forms[0], forms[1]);
        assert!(forms.iter().all(|f| f.is_ascii()));
        let named = provenance(&forms[2], &a.settings);
        let text = named.to_text(Region::full(64, 48));
        assert_eq!(Provenance::from_text(&text).unwrap().0, named);
    }
}
