//! `prism._prism`: the renderer library for Python. A front end beside the
//! command: it calls the library's public API only. The Python package
//! `prism` (pysrc/prism) wraps it with docstrings, the `Image` array type
//! and the dict form of scenes.
//!
//! A render runs on its own thread while the calling thread, without the
//! GIL most of the time, waits for it: every 50 ms it takes the GIL to let
//! Python handle signals (Ctrl-C cancels the render at the next row) and to
//! call the progress callback. Other Python threads run meanwhile.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, mpsc};
use std::time::Duration;

use glam::DVec3;
use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use prism::image_io::exr::Provenance;
use prism::image_io::{srgb8_of_f32, to_f32, write_film_unless};
use prism::render::aov::{Aov, render_aov};
use prism::render::explain::explain as explain_pixel;
use prism::render::{Film, Region, RenderError, render_region};
use prism::scene::LoadOptions;
use prism::scene::dict::{DictScene, MAX_NESTING, Problem, Value, too_deep_message};
use prism::text::escape_controls;
use prism::{RenderObserver, RenderSettings, SceneError as LoadError, limits};
use pyo3::create_exception;
use pyo3::exceptions::{
    PyException, PyKeyboardInterrupt, PyOSError, PyOverflowError, PyTypeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

mod rayscene;
mod recycle;

create_exception!(
    _prism,
    SceneError,
    PyException,
    "A scene that cannot be loaded. `.file`, `.line`, `.column` and `.message` locate \
     the first problem (line and column are None when the file could not be read); \
     `.problems` lists every problem as (line, column, message)."
);

/// One problem: line and column (none when the file could not be read,
/// or for a dict), and the message.
type Located = (Option<usize>, Option<usize>, String);
/// A region as (x0, x1, y0, y1).
type Bounds = (u32, u32, u32, u32);

/// A message from the library as a Python user should read it: the
/// command's option names as the Python arguments, and no control
/// character (from a name in a scene or model file) raw.
fn for_python(message: &str) -> String {
    escape_controls(message)
        .replace("--allow-read DIR", "allow_read=[DIR]")
        .replace("--allow-read", "allow_read")
        .replace("--camera ", "camera ")
        .replace("--width and --height", "width= and height=")
}

/// The scene error as a Python exception with its location. The message
/// is built here, one line per problem, each problem's text escaped.
fn scene_error(py: Python<'_>, e: &LoadError) -> PyErr {
    let (file, problems): (String, Vec<Located>) = match e {
        LoadError::Read { path, source } => (
            path.display().to_string(),
            vec![(
                None,
                None,
                for_python(&format!("cannot read the scene: {source}")),
            )],
        ),
        LoadError::Invalid {
            origin,
            diagnostics,
        } => (
            origin.clone(),
            diagnostics
                .iter()
                .map(|d| (Some(d.line), Some(d.column), for_python(&d.message)))
                .collect(),
        ),
    };
    let shown_file = escape_controls(&file).into_owned();
    let text = problems
        .iter()
        .map(|(line, column, message)| match (line, column) {
            (Some(l), Some(c)) => format!("{shown_file}:{l}:{c}: error: {message}"),
            _ => format!("{shown_file}: {message}"),
        })
        .collect::<Vec<_>>()
        .join("\n");
    located_error(py, text, file, problems, None)
}

/// A [`SceneError`] with its attributes.
fn located_error(
    py: Python<'_>,
    text: String,
    file: String,
    problems: Vec<Located>,
    key_path: Option<String>,
) -> PyErr {
    let err = SceneError::new_err(text.clone());
    let value = err.value(py);
    let first = problems.first().cloned().unwrap_or((None, None, text));
    let set = || -> PyResult<()> {
        value.setattr("file", file)?;
        value.setattr("line", first.0)?;
        value.setattr("column", first.1)?;
        value.setattr("message", first.2)?;
        value.setattr("problems", PyList::new(py, problems)?)?;
        value.setattr("key_path", key_path)?;
        Ok(())
    };
    match set() {
        Ok(()) => err,
        Err(e) => e,
    }
}

/// A dict scene's problems as a [`SceneError`]: `key_path` names the first
/// one's key, each message begins with its key path.
fn dict_error(py: Python<'_>, problems: Vec<Problem>) -> PyErr {
    let key_path = problems
        .first()
        .map(|p| p.key_path.clone())
        .filter(|k| !k.is_empty());
    let located: Vec<Located> = problems
        .iter()
        .map(|p| {
            let message = for_python(&p.message);
            let text = if p.key_path.is_empty() {
                message
            } else {
                format!("{}: {message}", p.key_path)
            };
            (None, None, text)
        })
        .collect();
    let text = located
        .iter()
        .map(|(_, _, m)| format!("<dict>: {m}"))
        .collect::<Vec<_>>()
        .join("\n");
    located_error(py, text, "<dict>".into(), located, key_path)
}

/// Where a scene came from, so that another animation frame can be built.
#[derive(Clone)]
enum Source {
    File(PathBuf),
    Text {
        text: String,
        origin: String,
        base_dir: PathBuf,
    },
    /// A dict, read again for another frame.
    Dict {
        dict: Arc<Py<PyAny>>,
        base_dir: PathBuf,
    },
}

/// A loaded scene: its geometry, lights, camera and render settings.
#[pyclass(module = "prism._prism", frozen)]
struct Scene {
    scene: Arc<prism::Scene>,
    source: Source,
    options: LoadOptions,
}

impl Scene {
    fn build(py: Python<'_>, source: Source, options: LoadOptions) -> PyResult<Scene> {
        if let Source::Dict { dict, base_dir } = &source {
            let assembled = dict_scene(py, dict.bind(py))?;
            let mut scene = py
                .detach(|| assembled.finish_at(base_dir, &options, 0.0))
                .map_err(|problems| dict_error(py, problems))?;
            // An open shutter on keyed values: the dict built again at
            // each instant (walked with the GIL, built without it).
            if let Some(shutter) = scene.settings.shutter.filter(|_| scene.animated) {
                scene
                    .motion_fits()
                    .map_err(|e| PyValueError::new_err(for_python(&e)))?;
                for k in 0..shutter.samples {
                    let assembled = dict_scene(py, dict.bind(py))?;
                    let offset = shutter.instant(k);
                    let instant = py
                        .detach(|| assembled.finish_at(base_dir, &options, offset))
                        .map_err(|problems| dict_error(py, problems))?;
                    scene.motion.push(instant);
                }
            }
            return Ok(Scene {
                scene: Arc::new(scene),
                source,
                options,
            });
        }
        let loaded = py.detach(|| match &source {
            Source::File(path) => prism::Scene::load_with(path, &options),
            Source::Text {
                text,
                origin,
                base_dir,
            } => prism::Scene::from_toml_with(text, origin, base_dir, &options),
            Source::Dict { .. } => unreachable!("built above"),
        });
        match loaded {
            Ok(scene) => Ok(Scene {
                scene: Arc::new(scene),
                source,
                options,
            }),
            Err(e) => Err(scene_error(py, &e)),
        }
    }

    /// The scene as built for `frame` (keyed values move with the frame).
    fn at_frame(&self, py: Python<'_>, frame: u32) -> PyResult<Arc<prism::Scene>> {
        if let Some(animation) = self.scene.animation
            && frame >= animation.frames
        {
            return Err(PyValueError::new_err(format!(
                "frame {frame} is past the animation's last frame {}",
                animation.frames - 1
            )));
        }
        if !self.scene.animated || frame == self.options.frame {
            return Ok(Arc::clone(&self.scene));
        }
        let options = LoadOptions {
            frame,
            ..self.options.clone()
        };
        Ok(Scene::build(py, self.source.clone(), options)?.scene)
    }

    /// The scene's settings with those given, each checked against the
    /// command's limits (prism::limits) and named when out of range.
    fn settings(
        &self,
        given: &Given<'_, '_>,
        threads: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<RenderSettings> {
        let s = &self.scene.settings;
        let side = u64::from(limits::MAX_IMAGE_SIDE);
        let settings = RenderSettings {
            width: opt_int("width", given.width, 1, side)?.map_or(s.width, |v| v as u32),
            height: opt_int("height", given.height, 1, side)?.map_or(s.height, |v| v as u32),
            spp: opt_int("spp", given.spp, 1, u64::from(limits::MAX_SPP))?
                .map_or(s.spp, |v| v as u32),
            max_depth: opt_int(
                "max_depth",
                given.max_depth,
                1,
                u64::from(limits::MAX_DEPTH),
            )?
            .map_or(s.max_depth, |v| v as u32),
            seed: opt_int("seed", given.seed, 0, u64::MAX)?.unwrap_or(s.seed),
            frame: frame_arg(given.frame)?,
            threads: opt_int("threads", threads, 1, u64::from(limits::MAX_THREADS))?
                .map(|v| v as usize),
            ..*s
        };
        settings
            .check()
            .map_err(|e| PyValueError::new_err(for_python(&e)))?;
        Ok(settings)
    }
}

/// Counts finished pixels and stops the render when asked.
struct Progress {
    done: AtomicU64,
    cancel: AtomicBool,
}

impl RenderObserver for Progress {
    fn tile_done(&self, _tile: Region, _pixels: &[DVec3], pixels_done: u64) {
        self.done.store(pixels_done, Ordering::Relaxed);
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

#[pymethods]
impl Scene {
    /// Renders the scene: linear radiance as float32, shape (H, W, 3) (the
    /// crop's shape with `crop`), equal bit for bit to the EXR
    /// `prism render` writes with the same settings.
    #[pyo3(signature = (width=None, height=None, spp=None, max_depth=None, seed=None,
                        frame=None, threads=None, crop=None, aov=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: Option<Bound<'py, PyAny>>,
        height: Option<Bound<'py, PyAny>>,
        spp: Option<Bound<'py, PyAny>>,
        max_depth: Option<Bound<'py, PyAny>>,
        seed: Option<Bound<'py, PyAny>>,
        frame: Option<Bound<'py, PyAny>>,
        threads: Option<Bound<'py, PyAny>>,
        crop: Option<Bound<'py, PyAny>>,
        aov: Option<&str>,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let given = Given {
            width: width.as_ref(),
            height: height.as_ref(),
            spp: spp.as_ref(),
            max_depth: max_depth.as_ref(),
            seed: seed.as_ref(),
            frame: frame.as_ref(),
        };
        let settings = self.settings(&given, threads.as_ref())?;
        let region = match crop {
            None => Region::full(settings.width, settings.height),
            Some(crop) => {
                let [x0, x1, y0, y1] = crop_arg(&crop)?;
                Region::crop(x0, x1, y0, y1, settings.width, settings.height)
                    .map_err(PyValueError::new_err)?
            }
        };
        let aov = aov
            .map(|a| {
                a.parse::<Aov>()
                    .map_err(|e| PyValueError::new_err(format!("aov: {}", for_python(&e))))
            })
            .transpose()?;
        let scene = self.at_frame(py, settings.frame)?;
        let observer = Arc::new(Progress {
            done: AtomicU64::new(0),
            cancel: AtomicBool::new(false),
        });
        let (send, receive) = mpsc::channel();
        // Waited on without the GIL, which needs a Sync handle.
        let receive = std::sync::Mutex::new(receive);
        let worker = {
            let (scene, observer) = (Arc::clone(&scene), Arc::clone(&observer));
            std::thread::spawn(move || {
                let out = match aov {
                    Some(aov) => render_aov(&scene, &settings, region, aov, observer.as_ref()),
                    None => render_region(&scene, &settings, region, observer.as_ref()),
                };
                let _ = send.send(out);
            })
        };
        let total = region.area();
        let stop = |why: PyErr| {
            observer.cancel.store(true, Ordering::Relaxed);
            let _ = worker_join(py, &receive);
            why
        };
        let output = loop {
            let waited = py.detach(|| match receive.lock() {
                Ok(r) => r.recv_timeout(Duration::from_millis(50)),
                Err(_) => Err(mpsc::RecvTimeoutError::Disconnected),
            });
            match waited {
                Ok(out) => break out,
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(PyException::new_err("the render thread failed"));
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            if let Err(e) = py.check_signals() {
                return Err(stop(e));
            }
            if let Some(callback) = &progress
                && let Err(e) = callback.call1((observer.done.load(Ordering::Relaxed), total))
            {
                return Err(stop(e));
            }
        };
        let _ = worker.join();
        let output = match output {
            Ok(o) => o,
            Err(RenderError::Cancelled) => {
                return Err(PyKeyboardInterrupt::new_err("the render was cancelled"));
            }
            Err(e) => return Err(PyValueError::new_err(e.to_string())),
        };
        if let Some(callback) = &progress {
            callback.call1((total, total))?;
        }
        // The radiance as an EXR stores it, moved into NumPy without a copy.
        let pixels: Vec<f32> = py.detach(|| {
            output
                .film
                .pixels()
                .iter()
                .flat_map(|p| [to_f32(p.x), to_f32(p.y), to_f32(p.z)])
                .collect()
        });
        let shape = [region.height() as usize, region.width() as usize, 3];
        Ok(pixels.into_pyarray(py).reshape(shape)?.into_any())
    }

    /// The ray tree of one sample of pixel (x, y), as the JSON text of
    /// `prism explain --json`.
    #[pyo3(signature = (x, y, sample=None, width=None, height=None, spp=None, max_depth=None,
                        seed=None, frame=None))]
    #[allow(clippy::too_many_arguments)]
    fn explain_json<'py>(
        &self,
        py: Python<'py>,
        x: Bound<'py, PyAny>,
        y: Bound<'py, PyAny>,
        sample: Option<Bound<'py, PyAny>>,
        width: Option<Bound<'py, PyAny>>,
        height: Option<Bound<'py, PyAny>>,
        spp: Option<Bound<'py, PyAny>>,
        max_depth: Option<Bound<'py, PyAny>>,
        seed: Option<Bound<'py, PyAny>>,
        frame: Option<Bound<'py, PyAny>>,
    ) -> PyResult<String> {
        let given = Given {
            width: width.as_ref(),
            height: height.as_ref(),
            spp: spp.as_ref(),
            max_depth: max_depth.as_ref(),
            seed: seed.as_ref(),
            frame: frame.as_ref(),
        };
        let settings = self.settings(&given, None)?;
        let side = u64::from(limits::MAX_IMAGE_SIDE);
        let x = int_arg("x", &x, 0, side - 1)? as u32;
        let y = int_arg("y", &y, 0, side - 1)? as u32;
        let sample = opt_int("sample", sample.as_ref(), 0, u64::from(limits::MAX_SPP) - 1)?
            .unwrap_or(0) as usize;
        let scene = self.at_frame(py, settings.frame)?;
        let explanation = py
            .detach(|| explain_pixel(&scene, &settings, x, y, sample))
            .map_err(PyValueError::new_err)?;
        serde_json::to_string(&explanation).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The scene's own render settings, as a dict.
    #[getter]
    fn settings_dict(&self) -> std::collections::BTreeMap<&'static str, f64> {
        let s = &self.scene.settings;
        [
            ("width", f64::from(s.width)),
            ("height", f64::from(s.height)),
            ("spp", f64::from(s.spp)),
            ("max_depth", f64::from(s.max_depth)),
            ("min_weight", s.min_weight),
            ("seed", s.seed as f64),
        ]
        .into_iter()
        .collect()
    }

    /// Warnings from loading, in file order.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.scene.warnings.clone()
    }

    /// Number of animation frames (1 for a still).
    #[getter]
    fn frames(&self) -> u32 {
        self.scene.animation.map_or(1, |a| a.frames)
    }
}

/// Waits for a render that was asked to stop.
fn worker_join<T: Send>(
    py: Python<'_>,
    receive: &std::sync::Mutex<mpsc::Receiver<T>>,
) -> Option<T> {
    py.detach(|| receive.lock().ok()?.recv().ok())
}

/// The read policy and frame, each folder of `allow_read` checked and
/// named when it is not one.
fn options(allow_read: Vec<PathBuf>, frame: Option<&Bound<'_, PyAny>>) -> PyResult<LoadOptions> {
    for dir in &allow_read {
        if dir.as_os_str().is_empty() {
            return Err(PyValueError::new_err(
                "allow_read: an empty path names no folder",
            ));
        }
        if !dir.is_dir() {
            return Err(PyValueError::new_err(format!(
                "allow_read: {} is not a folder",
                escape_controls(&dir.display().to_string())
            )));
        }
    }
    let mut options = LoadOptions::with_allow_read(&allow_read, limits::DEFAULT_TEXTURE_MIB)
        .map_err(|e| PyValueError::new_err(for_python(&e)))?;
    options.frame = frame_arg(frame)?;
    Ok(options)
}

/// `base_dir`, or the working folder; a path that is not a folder is named.
fn base_dir_arg(base_dir: Option<PathBuf>) -> PyResult<PathBuf> {
    match base_dir {
        Some(d) if d.is_dir() => Ok(d),
        Some(d) => Err(PyValueError::new_err(format!(
            "base_dir: {} is not a folder",
            escape_controls(&d.display().to_string())
        ))),
        None => std::env::current_dir().map_err(|e| PyOSError::new_err(e.to_string())),
    }
}

/// Loads a scene file (TOML) with the command line's read policy.
#[pyfunction]
#[pyo3(signature = (path, allow_read=Vec::new(), frame=None))]
fn load(
    py: Python<'_>,
    path: PathBuf,
    allow_read: Vec<PathBuf>,
    frame: Option<Bound<'_, PyAny>>,
) -> PyResult<Scene> {
    Scene::build(py, Source::File(path), options(allow_read, frame.as_ref())?)
}

/// Builds a scene from a dict with the scene file's keys, without TOML
/// text: problems are named by key path.
#[pyfunction]
#[pyo3(signature = (scene, base_dir=None, allow_read=Vec::new(), frame=None))]
fn from_dict(
    py: Python<'_>,
    scene: Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    allow_read: Vec<PathBuf>,
    frame: Option<Bound<'_, PyAny>>,
) -> PyResult<Scene> {
    let options = options(allow_read, frame.as_ref())?;
    let source = Source::Dict {
        dict: Arc::new(scene.unbind()),
        base_dir: base_dir_arg(base_dir)?,
    };
    Scene::build(py, source, options)
}

/// Loads a scene from TOML text; relative paths in it are read below
/// `base_dir`.
#[pyfunction]
#[pyo3(signature = (text, base_dir=None, origin="<string>".to_string(), allow_read=Vec::new(), frame=None))]
fn loads(
    py: Python<'_>,
    text: String,
    base_dir: Option<PathBuf>,
    origin: String,
    allow_read: Vec<PathBuf>,
    frame: Option<Bound<'_, PyAny>>,
) -> PyResult<Scene> {
    let options = options(allow_read, frame.as_ref())?;
    let source = Source::Text {
        text,
        origin,
        base_dir: base_dir_arg(base_dir)?,
    };
    Scene::build(py, source, options)
}

/// The pixels of an (H, W, 3) array as a film.
fn film_of(array: &PyReadonlyArray3<'_, f32>) -> PyResult<Film> {
    let shape = array.shape();
    if shape[2] != 3 || shape[0] == 0 || shape[1] == 0 {
        return Err(PyValueError::new_err(format!(
            "expected an array of shape (H, W, 3), got {shape:?}"
        )));
    }
    let (h, w) = (shape[0], shape[1]);
    if w > limits::MAX_IMAGE_SIDE as usize || h > limits::MAX_IMAGE_SIDE as usize {
        return Err(PyValueError::new_err(
            "the image is larger than Prism allows",
        ));
    }
    let view = array.as_array();
    let pixels: Vec<DVec3> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            DVec3::new(
                f64::from(view[[y, x, 0]]),
                f64::from(view[[y, x, 1]]),
                f64::from(view[[y, x, 2]]),
            )
        })
        .collect();
    let mut film = Film::new(w as u32, h as u32);
    film.paste(Region::full(w as u32, h as u32), &pixels);
    Ok(film)
}

/// Writes linear radiance to `path` (.png, .ppm: 8-bit sRGB clamped;
/// .exr, .hdr: linear float), atomically, as `prism render` writes it.
#[pyfunction]
fn write(py: Python<'_>, path: PathBuf, array: PyReadonlyArray3<'_, f32>) -> PyResult<()> {
    let film = film_of(&array)?;
    // An EXR carries the attribute `read_exr` (and `prism merge`) reads:
    // an array of this size, from Python. Any values: it may be a debug
    // view, so it is marked as one (its pixels are not checked as radiance).
    let provenance = Provenance {
        scene_hash: String::new(),
        camera: String::new(),
        settings: format!("{}x{} aov=array", film.width(), film.height()),
        seed: 0,
        frame: 0,
    };
    py.detach(|| write_film_unless(&film, &path, Some(&provenance), &AtomicBool::new(false)))
        .map_err(|e| PyOSError::new_err(for_python(&e.to_string())))
}

/// Linear radiance to 8-bit sRGB (clamped), as PNG output encodes it.
#[pyfunction]
fn to_srgb8<'py>(
    py: Python<'py>,
    array: PyReadonlyArray3<'py, f32>,
) -> PyResult<Bound<'py, PyAny>> {
    let shape = array.shape().to_vec();
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "expected an array of shape (H, W, 3), got {shape:?}"
        )));
    }
    let bytes: Vec<u8> = array.as_array().iter().map(|&v| srgb8_of_f32(v)).collect();
    Ok(bytes
        .into_pyarray(py)
        .reshape([shape[0], shape[1], 3])?
        .into_any())
}

/// Reads an EXR written by `prism render` (a whole frame or a part): its
/// pixels as float32 (H, W, 3) over its region, and the region
/// (x0, x1, y0, y1).
#[pyfunction]
fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyAny>, Bounds)> {
    let part = prism::image_io::read_part(Path::new(&path))
        .map_err(|e| PyValueError::new_err(for_python(&format!("{}: {e}", path.display()))))?;
    let r = part.film.region();
    let pixels: Vec<f32> = part
        .film
        .pixels()
        .iter()
        .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect();
    let array = pixels
        .into_pyarray(py)
        .reshape([r.height() as usize, r.width() as usize, 3])?
        .into_any();
    Ok((array, (r.x0, r.x1, r.y0, r.y1)))
}

#[pymodule]
fn _prism(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add_class::<Scene>()?;
    m.add_class::<rayscene::RayScene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(loads, m)?)?;
    m.add_function(wrap_pyfunction!(from_dict, m)?)?;
    m.add_function(wrap_pyfunction!(escape_controls_py, m)?)?;
    let limits = PyDict::new(m.py());
    limits.set_item("MAX_IMAGE_SIDE", limits::MAX_IMAGE_SIDE)?;
    limits.set_item("MAX_PIXELS", limits::MAX_PIXELS)?;
    limits.set_item("MAX_SPP", limits::MAX_SPP)?;
    limits.set_item("MAX_DEPTH", limits::MAX_DEPTH)?;
    limits.set_item("MAX_FRAMES", limits::MAX_FRAMES)?;
    limits.set_item("MAX_THREADS", limits::MAX_THREADS)?;
    m.add("LIMITS", limits)?;
    m.add_function(wrap_pyfunction!(write, m)?)?;
    m.add_function(wrap_pyfunction!(to_srgb8, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add("AOVS", Aov::ALL.iter().map(|(n, _)| *n).collect::<Vec<_>>())?;
    Ok(())
}

/// `text` with control characters escaped as the library escapes them in
/// its messages (`\n`, `\u{1b}`): for messages that show a user's string.
#[pyfunction]
#[pyo3(name = "escape_controls")]
fn escape_controls_py(text: &str) -> String {
    escape_controls(text).into_owned()
}

/// The render settings given to `render` or `explain` (None: the scene's).
struct Given<'a, 'py> {
    width: Option<&'a Bound<'py, PyAny>>,
    height: Option<&'a Bound<'py, PyAny>>,
    spp: Option<&'a Bound<'py, PyAny>>,
    max_depth: Option<&'a Bound<'py, PyAny>>,
    seed: Option<&'a Bound<'py, PyAny>>,
    frame: Option<&'a Bound<'py, PyAny>>,
}

/// An integer argument in `lo..=hi`; out of range (negative, too big for
/// any type) it is a ValueError naming the argument, not OverflowError.
fn int_arg(name: &str, value: &Bound<'_, PyAny>, lo: u64, hi: u64) -> PyResult<u64> {
    let out_of_range = || {
        PyValueError::new_err(format!(
            "{name} must be between {lo} and {hi}, got {}",
            value
                .str()
                .map_or_else(|_| "?".to_string(), |s| s.to_string())
        ))
    };
    if value.is_instance_of::<PyFloat>() || value.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "{name} must be an integer, got {}",
            value.get_type().name()?
        )));
    }
    match value.extract::<i128>() {
        Ok(v) if v >= i128::from(lo) && v <= i128::from(hi) => Ok(v as u64),
        Ok(_) => Err(out_of_range()),
        Err(e) if e.is_instance_of::<PyOverflowError>(value.py()) => Err(out_of_range()),
        Err(e) if e.is_instance_of::<PyTypeError>(value.py()) => {
            Err(PyTypeError::new_err(format!(
                "{name} must be an integer, got {}",
                value.get_type().name()?
            )))
        }
        Err(e) => Err(e),
    }
}

/// [`int_arg`] for an argument that may be None.
fn opt_int(
    name: &str,
    value: Option<&Bound<'_, PyAny>>,
    lo: u64,
    hi: u64,
) -> PyResult<Option<u64>> {
    match value {
        Some(v) if !v.is_none() => int_arg(name, v, lo, hi).map(Some),
        _ => Ok(None),
    }
}

/// An animation frame: 0 to the last frame Prism allows.
fn frame_arg(value: Option<&Bound<'_, PyAny>>) -> PyResult<u32> {
    Ok(opt_int("frame", value, 0, u64::from(limits::MAX_FRAMES) - 1)?.unwrap_or(0) as u32)
}

/// `crop=(x0, x1, y0, y1)`, each in range.
fn crop_arg(crop: &Bound<'_, PyAny>) -> PyResult<[u32; 4]> {
    let items: Vec<Bound<'_, PyAny>> = crop
        .try_iter()
        .and_then(|i| i.collect::<PyResult<Vec<_>>>())
        .map_err(|_| PyTypeError::new_err("crop must be (x0, x1, y0, y1)"))?;
    let [x0, x1, y0, y1] = &items[..] else {
        return Err(PyValueError::new_err(format!(
            "crop must be (x0, x1, y0, y1), got {} numbers",
            items.len()
        )));
    };
    let side = u64::from(limits::MAX_IMAGE_SIDE);
    Ok([
        int_arg("crop x0", x0, 0, side)? as u32,
        int_arg("crop x1", x1, 0, side)? as u32,
        int_arg("crop y0", y0, 0, side)? as u32,
        int_arg("crop y1", y1, 0, side)? as u32,
    ])
}

/// Why a dict value cannot be a scene value: the message, and the path to
/// it, innermost step first (filled in as the error returns). `deep`: it
/// nests past [`MAX_NESTING`], a scene problem (SceneError with its key
/// path, as the same value given to the library would be); anything else
/// is a value no scene holds (ValueError).
struct Unfit {
    message: String,
    steps: Vec<String>,
    deep: bool,
}

impl Unfit {
    fn at(mut self, step: String) -> Unfit {
        self.steps.push(step);
        self
    }

    fn into_err(self, py: Python<'_>) -> PyErr {
        let mut path = String::new();
        for step in self.steps.iter().rev() {
            if !step.starts_with('[') && !path.is_empty() {
                path.push('.');
            }
            path.push_str(step);
        }
        if self.deep {
            return dict_error(
                py,
                vec![Problem {
                    key_path: path,
                    message: self.message,
                }],
            );
        }
        PyValueError::new_err(format!("{path}: {}", self.message))
    }
}

/// A key as a path step, quoted when it is not a bare TOML key.
fn key_step(key: &str) -> String {
    if !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        key.to_string()
    } else {
        format!("{key:?}")
    }
}

type Fit<T> = Result<T, Unfit>;

fn unfit(message: String) -> Unfit {
    Unfit {
        message,
        steps: Vec::new(),
        deep: false,
    }
}

/// The key of a dict entry: a str.
fn dict_key(key: &Bound<'_, PyAny>) -> Fit<String> {
    match key.cast::<PyString>() {
        Ok(s) => s
            .to_cow()
            .map(|c| c.into_owned())
            .map_err(|e| unfit(e.to_string())),
        Err(_) => Err(unfit(format!(
            "keys are strings; found the key {} ({})",
            escape_controls(&key.repr().map_or_else(|_| "?".into(), |r| r.to_string())),
            key.get_type()
                .name()
                .map_or_else(|_| "?".into(), |n| n.to_string())
        ))),
    }
}

/// A Python value as a scene value: bool, int, float, str (and
/// os.PathLike), list and tuple, dict (and any Mapping), NumPy arrays and
/// scalars. Tables and lists nested past [`MAX_NESTING`] (counted as the
/// library counts them: the object's or section's value is level 1) are
/// refused before the walk goes deeper: it recurses once per level, and a
/// list that holds itself would recurse for ever.
fn value_of(obj: &Bound<'_, PyAny>) -> Fit<Value> {
    value_at(obj, 0, false)
}

/// [`value_of`] for a value below `above` tables and lists; `converted`:
/// it came from `tolist()`, not to be converted again (a `tolist` that
/// returns its own object would recurse for ever).
fn value_at(obj: &Bound<'_, PyAny>, above: usize, converted: bool) -> Fit<Value> {
    // The level of a table or list here, if it may be read.
    let level = || {
        if above >= MAX_NESTING {
            Err(Unfit {
                message: format!(
                    "{}; a list or dict that holds itself nests without end",
                    too_deep_message()
                ),
                steps: Vec::new(),
                deep: true,
            })
        } else {
            Ok(above + 1)
        }
    };
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if let Ok(f) = obj.cast::<PyFloat>() {
        return Ok(Value::Float(f.value()));
    }
    if obj.is_instance_of::<PyInt>() {
        return obj.extract::<i64>().map(Value::Integer).map_err(|_| {
            unfit(format!(
                "the integer {} is out of range (a scene's integers are 64-bit)",
                obj.str().map_or_else(|_| "?".into(), |s| s.to_string())
            ))
        });
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return s
            .to_cow()
            .map(|c| Value::String(c.into_owned()))
            .map_err(|e| unfit(e.to_string()));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let level = level()?;
        let mut entries = Vec::with_capacity(d.len());
        // A copy of the items: user code run below (`tolist`,
        // `__fspath__`) may resize the dict, which its iterator forbids.
        let items: Vec<(Bound<'_, PyAny>, Bound<'_, PyAny>)> =
            d.items().iter().filter_map(|i| i.extract().ok()).collect();
        for (k, v) in items {
            let key = dict_key(&k)?;
            match value_at(&v, level, false) {
                Ok(v) => entries.push((key, v)),
                Err(e) => return Err(e.at(key_step(&key))),
            }
        }
        return Ok(Value::Table(entries));
    }
    if let Ok(l) = obj.cast::<PyList>() {
        return items_of(l.iter(), level()?);
    }
    if let Ok(t) = obj.cast::<PyTuple>() {
        return items_of(t.iter(), level()?);
    }
    let py = obj.py();
    let other = |e: PyErr| unfit(e.to_string());
    if obj.hasattr("__fspath__").map_err(other)? {
        let path = py
            .import("os")
            .and_then(|os| os.call_method1("fspath", (obj,)))
            .map_err(other)?;
        // A str or bytes (os.fspath returns nothing else).
        return value_at(&path, above, true);
    }
    if !converted && obj.hasattr("tolist").map_err(other)? && !obj.is_instance_of::<PyString>() {
        // A NumPy array or scalar: its Python values.
        let plain = obj.call_method0("tolist").map_err(other)?;
        return value_at(&plain, above, true);
    }
    if let Ok(m) = obj.cast::<pyo3::types::PyMapping>() {
        let level = level()?;
        let mut entries = Vec::new();
        for item in m.items().map_err(other)?.iter() {
            let (k, v): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract().map_err(other)?;
            let key = dict_key(&k)?;
            match value_at(&v, level, false) {
                Ok(v) => entries.push((key, v)),
                Err(e) => return Err(e.at(key_step(&key))),
            }
        }
        return Ok(Value::Table(entries));
    }
    Err(unfit(format!(
        "cannot put a {} in a scene",
        obj.get_type()
            .name()
            .map_or_else(|_| "?".into(), |n| n.to_string())
    )))
}

/// The items of a list or tuple at `level`.
fn items_of<'py>(items: impl Iterator<Item = Bound<'py, PyAny>>, level: usize) -> Fit<Value> {
    let mut out = Vec::with_capacity(items.size_hint().0);
    for (i, item) in items.enumerate() {
        out.push(value_at(&item, level, false).map_err(|e| e.at(format!("[{i}]")))?);
    }
    Ok(Value::Array(out))
}

/// The dict walked into a [`DictScene`]: sections whole, objects one by
/// one (each goes into its checked form at once). Ctrl-C is heard every
/// 64k objects.
fn dict_scene(py: Python<'_>, scene: &Bound<'_, PyAny>) -> PyResult<DictScene> {
    let entries: Vec<(Bound<'_, PyAny>, Bound<'_, PyAny>)> = if let Ok(d) = scene.cast::<PyDict>() {
        d.iter().collect()
    } else if let Ok(m) = scene.cast::<pyo3::types::PyMapping>() {
        m.items()?
            .iter()
            .map(|i| i.extract())
            .collect::<PyResult<_>>()?
    } else {
        return Err(PyTypeError::new_err(format!(
            "a scene dict is a mapping of section names to tables, got {}",
            scene.get_type().name()?
        )));
    };
    let mut assembled = DictScene::new();
    for (k, v) in entries {
        let key = dict_key(&k).map_err(|e| e.into_err(py))?;
        let objects = if key == "objects" {
            // A NumPy array of objects: its list, so that each object is
            // read as one (and nests as deep as one in a list may).
            let v = if !v.is_instance_of::<PyList>()
                && !v.is_instance_of::<PyTuple>()
                && !v.is_instance_of::<PyString>()
                && v.hasattr("tolist")?
            {
                v.call_method0("tolist")?
            } else {
                v.clone()
            };
            v.cast::<PyList>()
                .map(|l| l.iter().collect::<Vec<_>>())
                .or_else(|_| v.cast::<PyTuple>().map(|t| t.iter().collect::<Vec<_>>()))
                .ok()
        } else {
            None
        };
        match objects {
            Some(items) => {
                for (i, item) in items.iter().enumerate() {
                    if i % 65_536 == 65_535 {
                        py.check_signals()?;
                    }
                    let value = value_of(item)
                        .map_err(|e| e.at(format!("[{i}]")).at("objects".into()).into_err(py))?;
                    assembled.object(value);
                }
            }
            None => {
                let value = value_of(&v).map_err(|e| e.at(key_step(&key)).into_err(py))?;
                assembled.section(&key, value);
            }
        }
    }
    Ok(assembled)
}
