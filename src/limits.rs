//! Every bound Prism puts on its input, stated once. The scene checks, the
//! command line, the model loaders and docs/scene-format.md ("Limits") all
//! use these, so a typo cannot exhaust memory, overflow the arithmetic or run
//! for ever, and the numbers a user reads are the numbers enforced.

/// Largest image width or height.
pub const MAX_IMAGE_SIDE: u32 = 32_768;
/// Most pixels in one image (a 16k × 16k film of f64 RGB is 6 GiB).
pub const MAX_PIXELS: u64 = 1 << 28;
/// Most samples per pixel.
pub const MAX_SPP: u32 = 65_536;
/// Deepest ray path (each level is a stack frame).
pub const MAX_DEPTH: u32 = 256;
/// Most frames of an animation (ten hours at 24 fps).
pub const MAX_FRAMES: u32 = 1_000_000;
/// Most worker threads a render may ask for (`--threads`, Python's
/// `threads=`): more than any machine has cores, few enough to start at once.
pub const MAX_THREADS: u32 = 1024;
/// Most cuts of adaptive anti-aliasing: at most (2⁹ + 1)² samples to a
/// pixel, and lattice coordinates (side × 2⁹) fit in 32 bits.
pub const MAX_ADAPTIVE_DEPTH: u32 = 8;
/// Most instants a shutter is sampled at (each is a scene built apart).
pub const MAX_SHUTTER_SAMPLES: u32 = 256;
/// Most memory an open shutter's instants may take together (each is a
/// copy of the scene: a million keyed spheres at 256 instants would not fit).
pub const MAX_SHUTTER_BYTES: u64 = 4 << 30;
/// Most shadow feelers per sphere light and shading point.
pub const MAX_LIGHT_SAMPLES: u32 = 65_536;

/// Largest |coordinate| of anything placed in the world (after transforms),
/// and the largest length (radius, size). Squares of lengths then stay far
/// from f64 overflow (1e60), and bounding boxes fit in f32 (3.4e38).
pub const MAX_COORDINATE: f64 = 1e30;
/// Smallest radius, size or scale factor; below it squares underflow.
pub const MIN_LENGTH: f64 = 1e-30;
/// Largest value of a colour component, light intensity or material
/// coefficient: products along a ray path stay finite in f64.
pub const MAX_VALUE: f64 = 1e15;

/// Most placements (glTF node instances) one model file may expand to.
pub const MAX_MODEL_PLACEMENTS: u64 = 1 << 20;
/// Most animation keys one model file's animation may read: its samplers'
/// key times and keyed values together (each stored in at most 32 bytes,
/// so 256 MiB), however many channels share them or accessors alias the
/// same bytes.
pub const MAX_ANIMATION_KEYS: u64 = 1 << 23;
/// Default budget for decoded texture memory per scene, in MiB
/// (`--texture-memory` raises it).
pub const DEFAULT_TEXTURE_MIB: u64 = 1024;

/// Most bytes of scene text one `[[objects]]` table may span, and most
/// bytes of all the text outside them: each is parsed into a syntax tree
/// about ten times its size. Large geometry belongs in a model file.
pub const MAX_TABLE_TEXT: usize = 16 << 20;

/// Most bytes of a scene file: text for ten million spheres. Read with
/// this bound, so `/dev/zero` or a runaway file cannot fill memory.
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 30;
/// Most bytes of any one file a scene reads (a model, its buffers, an MTL
/// file, a texture): a mesh of a hundred million triangles.
pub const MAX_FILE_BYTES: u64 = 8 << 30;

/// Deepest nesting of CSG operations (a CSG inside a CSG …): far past
/// what a scene needs, and a bound on the recursion that builds and
/// traces them.
pub const MAX_CSG_DEPTH: usize = 64;

/// The limits as the help text and docs state them.
pub fn describe() -> String {
    format!(
        "Limits: image sides 1..={MAX_IMAGE_SIDE} and at most {MAX_PIXELS} pixels; spp 1..={MAX_SPP}; \
         max_depth 1..={MAX_DEPTH}; adaptive depth 0..={MAX_ADAPTIVE_DEPTH}; shutter_samples 1..={MAX_SHUTTER_SAMPLES} (instants at most {} GiB in all); threads 1..={MAX_THREADS}; animation frames 1..={MAX_FRAMES}; sphere-light samples 1..={MAX_LIGHT_SAMPLES}; coordinates within \
         ±{MAX_COORDINATE:e} and lengths, radii and scale factors in [{MIN_LENGTH:e}, {MAX_COORDINATE:e}] \
         (after transforms); colours, intensities and coefficients at most {MAX_VALUE:e}; \
         {MAX_MODEL_PLACEMENTS} placements and {MAX_ANIMATION_KEYS} animation keys (times and values) per model file; CSG nested {MAX_CSG_DEPTH} deep; {} MiB of scene text per [[objects]] \
         table and outside them; {} MiB per scene file and {} MiB per file it reads; {DEFAULT_TEXTURE_MIB} MiB of textures unless --texture-memory \
         says otherwise.",
        MAX_SHUTTER_BYTES >> 30,
        MAX_TABLE_TEXT >> 20,
        MAX_SCENE_FILE_BYTES >> 20,
        MAX_FILE_BYTES >> 20,
    )
}
