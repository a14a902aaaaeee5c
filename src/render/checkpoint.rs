//! Resumable renders: each finished tile is saved to a folder as it
//! finishes (a temporary file renamed into place, so a tile file is whole
//! or absent whatever kills the process), and a later run of the same
//! render takes the saved tiles instead of tracing them again. The folder
//! is tied to one render by a manifest: another scene, other settings or
//! another region are refused rather than mixed in.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use glam::DVec3;
use sha2::{Digest, Sha256};

use super::Region;

/// First bytes of a tile file.
const MAGIC: &[u8; 8] = b"PRISMTL1";
/// Size of a tile file of the largest tile (see `encode`).
const MAX_TILE_BYTES: u64 = 8 + 16 + (super::TILE as u64 * super::TILE as u64) * 24 + 32;
/// The manifest's file name.
const MANIFEST: &str = "checkpoint.txt";
/// The most a manifest (a render's key, a few short lines) holds.
const MAX_MANIFEST_BYTES: u64 = 1 << 16;

/// A checkpoint folder opened for one render.
pub struct Checkpoint {
    dir: PathBuf,
    /// The render's key: every tile's digest covers it, so a tile of
    /// another render is not taken.
    key: String,
    saved: Mutex<HashMap<Region, Vec<DVec3>>>,
    resumed: usize,
}

impl Checkpoint {
    /// Opens (creating if needed) the checkpoint in `dir` for the render
    /// identified by `key` (what the pixels depend on, and the region),
    /// loading the tiles an earlier run saved. Refuses a folder that holds
    /// another render's checkpoint, naming the line that differs.
    pub fn open(dir: &Path, key: &str) -> Result<Checkpoint, String> {
        std::fs::create_dir_all(dir).map_err(|e| {
            format!(
                "{}: cannot create the checkpoint folder: {e}",
                dir.display()
            )
        })?;
        let manifest = dir.join(MANIFEST);
        // A manifest is a key of a few lines: read as a regular file, and
        // no more of it than a key can be.
        let read = crate::scene::resources::read_regular(
            &manifest,
            crate::scene::resources::Extent::Whole(MAX_MANIFEST_BYTES),
        )
        .and_then(|b| {
            String::from_utf8(b)
                .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))
        });
        match read {
            Ok(old) if old == key => {}
            Ok(old) => {
                // Named by the option that differs (its camera, spp, …).
                let differs = crate::image_io::Provenance::key_difference(key, &old)
                    .map_or(String::new(), |d| format!(" ({d})"));
                return Err(format!(
                    "{}: holds the checkpoint of another render{differs}; \
                     use another folder or delete this one",
                    dir.display()
                ));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // A run killed while writing the manifest leaves only its
                // temporary file: the folder is still new.
                remove_leftover_temporaries(dir);
                if std::fs::read_dir(dir).map_or(true, |mut d| d.next().is_some()) {
                    return Err(format!(
                        "{}: is not empty and holds no checkpoint; give an empty or new folder",
                        dir.display()
                    ));
                }
                write_atomically(&manifest, key.as_bytes())
                    .map_err(|e| format!("{}: {e}", manifest.display()))?;
            }
            Err(e) => return Err(format!("{}: {e}", manifest.display())),
        }
        let mut saved = HashMap::new();
        let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        for entry in entries.flatten() {
            let path = entry.path();
            // No tile of a render is larger than this; a larger file is
            // not ours and is not read into memory.
            let fits = entry.metadata().is_ok_and(|m| m.len() <= MAX_TILE_BYTES);
            if fits && path.extension().is_some_and(|e| e == "tile") {
                // A damaged tile, one of another render, or one moved from
                // its place is traced again, not trusted.
                // Read as a regular file of at most a tile's size (a FIFO
                // or a link to a device named `*.tile` is skipped).
                let decoded = crate::scene::resources::read_regular(
                    &path,
                    crate::scene::resources::Extent::Whole(MAX_TILE_BYTES),
                )
                .ok()
                .and_then(|b| decode(key, &b));
                if let Some((region, pixels)) = decoded
                    && path.file_name() == Some(tile_name(region).as_ref())
                {
                    saved.insert(region, pixels);
                }
            }
        }
        Ok(Checkpoint {
            dir: dir.to_path_buf(),
            key: key.to_string(),
            resumed: saved.len(),
            saved: Mutex::new(saved),
        })
    }

    /// How many tiles an earlier run left.
    pub fn resumed(&self) -> usize {
        self.resumed
    }

    /// The saved pixels of `tile`, if an earlier run finished it.
    pub fn take(&self, tile: Region) -> Option<Vec<DVec3>> {
        self.saved
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .remove(&tile)
            .filter(|p| p.len() as u64 == tile.area())
    }

    /// Saves a finished tile.
    pub fn save(&self, tile: Region, pixels: &[DVec3]) -> Result<(), String> {
        let path = self.dir.join(tile_name(tile));
        write_atomically(&path, &encode(&self.key, tile, pixels))
            .map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Removes the checkpoint once the image is written.
    pub fn remove(self) -> std::io::Result<()> {
        for entry in std::fs::read_dir(&self.dir)?.flatten() {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "tile" || e == "part") {
                std::fs::remove_file(path)?;
            }
        }
        // The manifest last: a run killed part way leaves a checkpoint the
        // next run still takes, not tiles without one (which it refuses).
        match std::fs::remove_file(self.dir.join(MANIFEST)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
            _ => {}
        }
        std::fs::remove_dir(&self.dir)
    }
}

/// A tile's file name: its position in the frame.
fn tile_name(tile: Region) -> String {
    format!("{}-{}.tile", tile.x0, tile.y0)
}

/// How `write_atomically` names its temporary files.
const TEMP_PREFIX: &str = ".tile-";
const TEMP_SUFFIX: &str = ".part";

/// Removes the temporary files a killed run left in `dir` (plain files
/// named as `write_atomically` names them; nothing else is touched).
fn remove_leftover_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        let ours = name.starts_with(TEMP_PREFIX) && name.ends_with(TEMP_SUFFIX);
        if ours && entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Writes `bytes` to a temporary file beside `path` and renames it there.
fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut temp = tempfile::Builder::new()
        .prefix(TEMP_PREFIX)
        .suffix(TEMP_SUFFIX)
        .tempfile_in(dir)?;
    temp.write_all(bytes)?;
    temp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Magic, the region (4 × u32), the pixels (f64 RGB), all little-endian,
/// then the SHA-256 of the render's key and everything before it.
fn encode(key: &str, tile: Region, pixels: &[DVec3]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(8 + 16 + pixels.len() * 24 + 32);
    bytes.extend_from_slice(MAGIC);
    for v in [tile.x0, tile.x1, tile.y0, tile.y1] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for p in pixels {
        for c in p.to_array() {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let digest = keyed_digest(key, &bytes);
    bytes.extend_from_slice(&digest);
    bytes
}

fn keyed_digest(key: &str, body: &[u8]) -> [u8; 32] {
    let mut hash = Sha256::new();
    hash.update((key.len() as u64).to_le_bytes());
    hash.update(key.as_bytes());
    hash.update(body);
    hash.finalize().into()
}

/// The tile in `bytes`, if it is whole and was saved for the render `key`.
fn decode(key: &str, bytes: &[u8]) -> Option<(Region, Vec<DVec3>)> {
    let (body, digest) = bytes.split_at_checked(bytes.len().checked_sub(32)?)?;
    if keyed_digest(key, body).as_slice() != digest || !body.starts_with(MAGIC) {
        return None;
    }
    let word =
        |i: usize| u32::from_le_bytes(body[8 + 4 * i..12 + 4 * i].try_into().unwrap_or_default());
    if body.len() < 24 {
        return None;
    }
    let (x0, x1, y0, y1) = (word(0), word(1), word(2), word(3));
    if x0 >= x1 || y0 >= y1 {
        return None;
    }
    let region = Region { x0, x1, y0, y1 };
    let data = &body[24..];
    if data.len() as u64 != region.area() * 24 {
        return None;
    }
    let pixels = data
        .chunks_exact(24)
        .map(|c| {
            let f =
                |i: usize| f64::from_le_bytes(c[8 * i..8 * i + 8].try_into().unwrap_or_default());
            DVec3::new(f(0), f(1), f(2))
        })
        .collect();
    Some((region, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_round_trip_and_damage_is_detected() {
        let tile = Region {
            x0: 16,
            x1: 20,
            y0: 0,
            y1: 2,
        };
        let pixels: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new(i as f64, 0.1, -3.5e300))
            .collect();
        let bytes = encode("k", tile, &pixels);
        assert_eq!(decode("k", &bytes), Some((tile, pixels)));
        // Another render's key: not taken.
        assert_eq!(decode("k2", &bytes), None);
        for cut in [0, 10, bytes.len() - 1] {
            assert_eq!(decode("k", &bytes[..cut]), None);
        }
        let mut flipped = bytes.clone();
        flipped[40] ^= 1;
        assert_eq!(decode("k", &flipped), None);
    }

    /// A run killed while writing the manifest leaves only the manifest's
    /// temporary file; the next run takes the folder as new, and still
    /// refuses a folder holding anything else.
    #[test]
    fn a_folder_holding_only_a_killed_runs_temporary_is_new() {
        let dir = tempfile::tempdir().unwrap();
        let at = dir.path().join("cp");
        std::fs::create_dir(&at).unwrap();
        let leftover = at.join(".tile-Ab3xYz.part");
        std::fs::write(&leftover, b"scene=a\nreg").unwrap();
        let c = Checkpoint::open(&at, "scene=a\n").unwrap();
        assert_eq!(c.resumed(), 0);
        assert!(!leftover.exists());
        assert_eq!(
            std::fs::read_to_string(at.join(MANIFEST)).unwrap(),
            "scene=a\n"
        );
        let other = dir.path().join("other");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(other.join(".tile-Ab3xYz.part"), b"").unwrap();
        std::fs::write(other.join("notes.txt"), b"mine").unwrap();
        let refused = Checkpoint::open(&other, "scene=a\n").err().unwrap();
        assert!(refused.contains("holds no checkpoint"), "{refused}");
        assert!(other.join("notes.txt").exists());
    }

    #[test]
    fn a_checkpoint_resumes_and_refuses_another_render() {
        let dir = tempfile::tempdir().unwrap();
        let at = dir.path().join("cp");
        let tile = Region {
            x0: 0,
            x1: 2,
            y0: 0,
            y1: 1,
        };
        let c = Checkpoint::open(&at, "scene=a\nregion=0,2,0,1\n").unwrap();
        assert_eq!(c.resumed(), 0);
        c.save(tile, &[DVec3::ONE, DVec3::X]).unwrap();
        let c = Checkpoint::open(&at, "scene=a\nregion=0,2,0,1\n").unwrap();
        assert_eq!(c.resumed(), 1);
        assert_eq!(c.take(tile), Some(vec![DVec3::ONE, DVec3::X]));
        let e = Checkpoint::open(&at, "scene=b\nregion=0,2,0,1\n")
            .err()
            .unwrap();
        assert!(e.contains("another render") && e.contains("scene=b"), "{e}");
        // A tile of another render (same region, other key), and a tile
        // moved to another tile's name, are traced again.
        let other =
            Checkpoint::open(&dir.path().join("other"), "scene=b\nregion=0,2,0,1\n").unwrap();
        other.save(tile, &[DVec3::X, DVec3::X]).unwrap();
        std::fs::copy(dir.path().join("other/0-0.tile"), at.join("0-0.tile")).unwrap();
        assert_eq!(
            Checkpoint::open(&at, "scene=a\nregion=0,2,0,1\n")
                .unwrap()
                .resumed(),
            0
        );
        c.save(tile, &[DVec3::ONE, DVec3::X]).unwrap();
        std::fs::rename(at.join("0-0.tile"), at.join("0-1.tile")).unwrap();
        assert_eq!(
            Checkpoint::open(&at, "scene=a\nregion=0,2,0,1\n")
                .unwrap()
                .resumed(),
            0
        );
        c.remove().unwrap();
        assert!(!at.exists());
        // A folder with other files in it is not taken over.
        std::fs::write(dir.path().join("x"), "x").unwrap();
        assert!(Checkpoint::open(dir.path(), "k").is_err());
    }
}
