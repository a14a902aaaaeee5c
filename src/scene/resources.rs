//! The files a scene reads, and what they cost.
//!
//! **What may be read**, after POV-Ray's I/O restrictions: files below the
//! scene's own folder and below folders the user allows (`--allow-read DIR`,
//! `PRISM_ALLOW_READ` for farms). Paths are resolved, symlinks included,
//! before the check, so neither `../..`, an absolute path, a `file://` URI
//! nor a link inside the folder leads out of it. Only regular files are
//! read (`/dev/zero` named as a model is refused, not read for ever).
//!
//! **Textures** are decoded once per scene however many materials use them,
//! within a memory budget checked from the image header before decoding.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use sha2::{Digest, Sha256};

use crate::limits;
use crate::shading::texture::ImageTexture;

/// How a scene is loaded: what it may read and how much texture memory it
/// may use.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadOptions {
    /// Folders the scene may read besides its own (and their subfolders).
    pub allow_read: Vec<PathBuf>,
    /// Budget for decoded textures, in bytes.
    pub texture_budget: u64,
    /// The animation frame to build: keyed values are taken at it.
    pub frame: u32,
    /// The model camera to look through (`--camera NAME`), by its node's
    /// or its own name; it takes the place of the scene's camera.
    pub camera: Option<String>,
}

impl LoadOptions {
    /// The read policy every front end applies: a scene reads below its
    /// own folder, below each of `allow_read`, and below each folder of
    /// the environment variable PRISM_ALLOW_READ (separated by `:`);
    /// decoded textures may take `texture_mib` MiB. A folder that does not
    /// exist is an error, named.
    pub fn with_allow_read(allow_read: &[PathBuf], texture_mib: u64) -> Result<Self, String> {
        let from_env = std::env::var_os("PRISM_ALLOW_READ")
            .map(|v| std::env::split_paths(&v).collect::<Vec<_>>())
            .unwrap_or_default();
        let mut dirs = Vec::new();
        for dir in allow_read.iter().chain(&from_env) {
            if dir.as_os_str().is_empty() {
                continue;
            }
            if !dir.is_dir() {
                return Err(format!(
                    "{}: --allow-read (or PRISM_ALLOW_READ) names no folder",
                    dir.display()
                ));
            }
            dirs.push(dir.clone());
        }
        Ok(LoadOptions {
            allow_read: dirs,
            texture_budget: texture_mib.saturating_mul(1 << 20),
            frame: 0,
            camera: None,
        })
    }
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            allow_read: Vec::new(),
            texture_budget: limits::DEFAULT_TEXTURE_MIB << 20,
            frame: 0,
            camera: None,
        }
    }
}

/// A file a scene read, resolved, and the SHA-256 of its bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileRead {
    /// The resolved path.
    pub path: PathBuf,
    /// SHA-256 of its contents.
    pub sha256: [u8; 32],
}

/// The folders a scene may read.
#[derive(Clone, Debug)]
pub struct ReadPolicy {
    roots: Vec<PathBuf>,
    /// Every file read so far with the SHA-256 of its bytes, in read order:
    /// what the scene's content hash covers and a preview watches.
    reads: Arc<Mutex<Vec<FileRead>>>,
}

impl ReadPolicy {
    /// Reading below `scene_dir` and below each of `allowed`.
    pub fn new(scene_dir: &Path, allowed: &[PathBuf]) -> ReadPolicy {
        let roots = std::iter::once(scene_dir)
            .chain(allowed.iter().map(PathBuf::as_path))
            .map(|d| d.canonicalize().unwrap_or_else(|_| d.to_path_buf()))
            .collect();
        ReadPolicy {
            roots,
            reads: Arc::default(),
        }
    }

    /// The resolved path of `path` if the scene may read it; the message
    /// (to follow the path the caller names) says how to allow it.
    pub fn check(&self, path: &Path) -> Result<PathBuf, String> {
        let resolved = path
            .canonicalize()
            .map_err(|e| format!("cannot read: {e}"))?;
        if self.roots.iter().any(|root| resolved.starts_with(root)) {
            Ok(resolved)
        } else {
            Err(format!(
                "refused: it resolves to {}, outside the folders this scene may read ({}); \
                 allow its folder with --allow-read DIR (or PRISM_ALLOW_READ)",
                resolved.display(),
                self.roots
                    .iter()
                    .map(|r| r.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        }
    }

    /// The whole of the regular file at `path`, if the scene may read it
    /// and it holds at most [`limits::MAX_FILE_BYTES`].
    pub fn read(&self, path: &Path) -> Result<Vec<u8>, String> {
        self.read_as(path, Extent::Whole(limits::MAX_FILE_BYTES))
    }

    /// The first `len` bytes of the regular file at `path` (a glTF buffer
    /// of a declared `byteLength`): only they are read and hashed; a
    /// shorter file is refused.
    pub fn read_prefix(&self, path: &Path, len: u64) -> Result<Vec<u8>, String> {
        if len > limits::MAX_FILE_BYTES {
            return Err(format!(
                "{len} bytes are declared, more than {}, the most Prism reads of one file",
                limits::MAX_FILE_BYTES
            ));
        }
        self.read_as(path, Extent::Prefix(len))
    }

    fn read_as(&self, path: &Path, extent: Extent) -> Result<Vec<u8>, String> {
        let resolved = self.check(path)?;
        let bytes = read_regular(&resolved, extent).map_err(|e| e.to_string())?;
        let digest = Sha256::digest(&bytes).into();
        self.reads
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(FileRead {
                path: resolved,
                sha256: digest,
            });
        Ok(bytes)
    }

    /// The files read so far and the SHA-256 of each, in read order.
    pub fn files_read(&self) -> Vec<FileRead> {
        self.reads.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// How much of a file to read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Extent {
    /// All of it, refused when longer than this many bytes.
    Whole(u64),
    /// Exactly this many bytes from its start, refused when shorter.
    Prefix(u64),
}

/// Reads the regular file at `path` as `extent` says, never more than the
/// extent's bytes plus one. Anything but a regular file (a device such as
/// `/dev/zero`, a FIFO, a socket, a folder) is refused before it is
/// opened: opening a FIFO with no writer would wait for ever, and reading a
/// device would never end. The file is opened non-blocking and checked
/// again, so one swapped in between the two looks is refused too.
pub fn read_regular(path: &Path, extent: Extent) -> std::io::Result<Vec<u8>> {
    use std::io::{Error, ErrorKind, Read};
    let not_regular = || {
        Error::new(
            ErrorKind::InvalidInput,
            "not a regular file (a device, FIFO, socket or folder); expected a file to read",
        )
    };
    let too_large = |limit: u64| {
        Error::new(
            ErrorKind::InvalidData,
            format!("the file is larger than {limit} bytes, the most Prism reads of such a file"),
        )
    };
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
    let file = options.open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    if let Extent::Whole(limit) = extent
        && meta.len() > limit
    {
        // Said before reading; the bound below holds for a file that grows.
        return Err(too_large(limit));
    }
    let (cap, want) = match extent {
        Extent::Whole(limit) => (limit, limit.saturating_add(1)),
        Extent::Prefix(len) => (len, len),
    };
    let mut bytes = Vec::with_capacity(meta.len().min(cap) as usize);
    file.take(want).read_to_end(&mut bytes)?;
    match extent {
        Extent::Whole(limit) if bytes.len() as u64 > limit => Err(too_large(limit)),
        Extent::Prefix(len) if (bytes.len() as u64) < len => Err(Error::new(
            ErrorKind::UnexpectedEof,
            format!(
                "{len} bytes are declared, but the file holds only {}",
                bytes.len()
            ),
        )),
        _ => Ok(bytes),
    }
}

/// What a texture is known by in the cache: its file, or (for images inside
/// a glTF file) the model file and the image's index.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum TextureKey {
    /// An image file, resolved.
    File(PathBuf),
    /// Image `index` of the model file (resolved).
    Embedded(PathBuf, usize),
}

/// Files read while building one scene: the policy, and textures decoded
/// once within a budget.
#[derive(Debug)]
pub struct Resources {
    /// What may be read.
    pub policy: ReadPolicy,
    textures: HashMap<TextureKey, Arc<ImageTexture>>,
    texture_bytes: u64,
    texture_budget: u64,
}

impl Resources {
    /// Resources for a scene in `scene_dir` loaded with `options`.
    pub fn new(scene_dir: &Path, options: &LoadOptions) -> Resources {
        Resources {
            policy: ReadPolicy::new(scene_dir, &options.allow_read),
            textures: HashMap::new(),
            texture_bytes: 0,
            texture_budget: options.texture_budget,
        }
    }

    /// Bytes of texture memory in use.
    pub fn texture_bytes(&self) -> u64 {
        self.texture_bytes
    }

    /// Textures decoded so far.
    pub fn texture_count(&self) -> usize {
        self.textures.len()
    }

    /// The image file at `path`, decoded once.
    pub fn texture_file(&mut self, path: &Path) -> Result<Arc<ImageTexture>, String> {
        let resolved = self.policy.check(path)?;
        let key = TextureKey::File(resolved);
        if let Some(t) = self.textures.get(&key) {
            return Ok(t.clone());
        }
        let bytes = self.policy.read(path)?;
        self.decode(key, &bytes)
    }

    /// The image `bytes` known by `key`, decoded once.
    pub fn texture_bytes_of(
        &mut self,
        key: TextureKey,
        bytes: &[u8],
    ) -> Result<Arc<ImageTexture>, String> {
        if let Some(t) = self.textures.get(&key) {
            return Ok(t.clone());
        }
        self.decode(key, bytes)
    }

    fn decode(&mut self, key: TextureKey, bytes: &[u8]) -> Result<Arc<ImageTexture>, String> {
        let left = self.texture_budget.saturating_sub(self.texture_bytes);
        let reader = image::ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())?;
        let texture = ImageTexture::decode(reader, left).map_err(|e| match e {
            crate::shading::texture::DecodeError::OverBudget { needed } => format!(
                "needs {} MiB decoded, but only {} MiB of the {} MiB texture budget are left; \
                 raise it with --texture-memory MIB",
                needed.div_ceil(1 << 20),
                left >> 20,
                self.texture_budget >> 20
            ),
            crate::shading::texture::DecodeError::Image(m) => m,
        })?;
        self.texture_bytes += texture.memory_bytes() as u64;
        let texture = Arc::new(texture);
        self.textures.insert(key, texture.clone());
        Ok(texture)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_only_below_the_allowed_folders() {
        let dir = tempfile::tempdir().unwrap();
        let scene_dir = dir.path().join("scene");
        let other = dir.path().join("other");
        std::fs::create_dir_all(scene_dir.join("sub")).unwrap();
        std::fs::create_dir_all(&other).unwrap();
        std::fs::write(scene_dir.join("sub/a.txt"), b"a").unwrap();
        std::fs::write(other.join("b.txt"), b"b").unwrap();
        let policy = ReadPolicy::new(&scene_dir, &[]);
        assert_eq!(policy.read(&scene_dir.join("sub/a.txt")).unwrap(), b"a");
        // `..` out of the folder, and a link inside it pointing out.
        let e = policy
            .read(&scene_dir.join("sub/../../other/b.txt"))
            .unwrap_err();
        assert!(e.contains("--allow-read"), "{e}");
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(other.join("b.txt"), scene_dir.join("link")).unwrap();
            assert!(policy.read(&scene_dir.join("link")).is_err());
        }
        let allowed = ReadPolicy::new(&scene_dir, std::slice::from_ref(&other));
        assert_eq!(allowed.read(&other.join("b.txt")).unwrap(), b"b");
        // Not a regular file.
        assert!(
            allowed
                .read(&other)
                .unwrap_err()
                .contains("not a regular file")
        );
    }
}
