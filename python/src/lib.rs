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
use prism::image_io::{srgb8_of_f32, to_f32, write_film};
use prism::render::aov::{Aov, render_aov};
use prism::render::explain::explain as explain_pixel;
use prism::render::{Film, Region, RenderError, render_region};
use prism::scene::LoadOptions;
use prism::{RenderObserver, RenderSettings, SceneError as LoadError, limits};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyList;

create_exception!(
    _prism,
    SceneError,
    PyException,
    "A scene that cannot be loaded. `.file`, `.line`, `.column` and `.message` locate \
     the first problem (line and column are None when the file could not be read); \
     `.problems` lists every problem as (line, column, message)."
);

/// One problem: line and column (none when the file could not be read),
/// and the message.
type Problem = (Option<usize>, Option<usize>, String);
/// A region as (x0, x1, y0, y1).
type Bounds = (u32, u32, u32, u32);

/// The scene error as a Python exception with its location.
fn scene_error(py: Python<'_>, e: &LoadError) -> PyErr {
    let err = SceneError::new_err(e.to_string());
    let value = err.value(py);
    let (file, problems): (String, Vec<Problem>) = match e {
        LoadError::Read { path, source } => (
            path.display().to_string(),
            vec![(None, None, format!("cannot read the scene: {source}"))],
        ),
        LoadError::Invalid {
            origin,
            diagnostics,
        } => (
            origin.clone(),
            diagnostics
                .iter()
                .map(|d| (Some(d.line), Some(d.column), d.message.clone()))
                .collect(),
        ),
    };
    let first = problems
        .first()
        .cloned()
        .unwrap_or((None, None, e.to_string()));
    let set = || -> PyResult<()> {
        value.setattr("file", file)?;
        value.setattr("line", first.0)?;
        value.setattr("column", first.1)?;
        value.setattr("message", first.2)?;
        value.setattr("problems", PyList::new(py, problems)?)?;
        Ok(())
    };
    match set() {
        Ok(()) => err,
        Err(e) => e,
    }
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
        let loaded = py.detach(|| match &source {
            Source::File(path) => prism::Scene::load_with(path, &options),
            Source::Text {
                text,
                origin,
                base_dir,
            } => prism::Scene::from_toml_with(text, origin, base_dir, &options),
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

    #[allow(clippy::too_many_arguments)]
    fn settings(
        &self,
        width: Option<u32>,
        height: Option<u32>,
        spp: Option<u32>,
        max_depth: Option<u32>,
        seed: Option<u64>,
        frame: u32,
        threads: Option<usize>,
    ) -> PyResult<RenderSettings> {
        let s = &self.scene.settings;
        let settings = RenderSettings {
            width: width.unwrap_or(s.width),
            height: height.unwrap_or(s.height),
            spp: spp.unwrap_or(s.spp),
            max_depth: max_depth.unwrap_or(s.max_depth),
            seed: seed.unwrap_or(s.seed),
            frame,
            threads,
            ..*s
        };
        settings.check().map_err(PyValueError::new_err)?;
        if threads == Some(0) {
            return Err(PyValueError::new_err("threads must be at least 1"));
        }
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
                        frame=0, threads=None, crop=None, aov=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: Option<u32>,
        height: Option<u32>,
        spp: Option<u32>,
        max_depth: Option<u32>,
        seed: Option<u64>,
        frame: u32,
        threads: Option<usize>,
        crop: Option<Bounds>,
        aov: Option<&str>,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let settings = self.settings(width, height, spp, max_depth, seed, frame, threads)?;
        let region = match crop {
            None => Region::full(settings.width, settings.height),
            Some((x0, x1, y0, y1)) => Region::crop(x0, x1, y0, y1, settings.width, settings.height)
                .map_err(PyValueError::new_err)?,
        };
        let aov = aov
            .map(|a| a.parse::<Aov>().map_err(PyValueError::new_err))
            .transpose()?;
        let scene = self.at_frame(py, frame)?;
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
    #[pyo3(signature = (x, y, sample=0, width=None, height=None, spp=None, max_depth=None,
                        seed=None, frame=0))]
    #[allow(clippy::too_many_arguments)]
    fn explain_json(
        &self,
        py: Python<'_>,
        x: u32,
        y: u32,
        sample: usize,
        width: Option<u32>,
        height: Option<u32>,
        spp: Option<u32>,
        max_depth: Option<u32>,
        seed: Option<u64>,
        frame: u32,
    ) -> PyResult<String> {
        let settings = self.settings(width, height, spp, max_depth, seed, frame, None)?;
        let scene = self.at_frame(py, frame)?;
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

fn options(allow_read: Vec<PathBuf>, frame: u32) -> PyResult<LoadOptions> {
    let mut options = LoadOptions::with_allow_read(&allow_read, limits::DEFAULT_TEXTURE_MIB)
        .map_err(PyValueError::new_err)?;
    options.frame = frame;
    Ok(options)
}

/// Loads a scene file (TOML) with the command line's read policy.
#[pyfunction]
#[pyo3(signature = (path, allow_read=Vec::new(), frame=0))]
fn load(py: Python<'_>, path: PathBuf, allow_read: Vec<PathBuf>, frame: u32) -> PyResult<Scene> {
    Scene::build(py, Source::File(path), options(allow_read, frame)?)
}

/// Loads a scene from TOML text; relative paths in it are read below
/// `base_dir`.
#[pyfunction]
#[pyo3(signature = (text, base_dir=None, origin="<string>".to_string(), allow_read=Vec::new(), frame=0))]
fn loads(
    py: Python<'_>,
    text: String,
    base_dir: Option<PathBuf>,
    origin: String,
    allow_read: Vec<PathBuf>,
    frame: u32,
) -> PyResult<Scene> {
    let base_dir = match base_dir {
        Some(d) => d,
        None => std::env::current_dir().map_err(|e| PyOSError::new_err(e.to_string()))?,
    };
    let source = Source::Text {
        text,
        origin,
        base_dir,
    };
    Scene::build(py, source, options(allow_read, frame)?)
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
    py.detach(|| write_film(&film, &path))
        .map_err(|e| PyOSError::new_err(e.to_string()))
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
        .map_err(|e| PyValueError::new_err(format!("{}: {e}", path.display())))?;
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
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(loads, m)?)?;
    m.add_function(wrap_pyfunction!(write, m)?)?;
    m.add_function(wrap_pyfunction!(to_srgb8, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add("AOVS", Aov::ALL.iter().map(|(n, _)| *n).collect::<Vec<_>>())?;
    Ok(())
}
