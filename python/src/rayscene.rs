//! `prism._prism.RayScene`: the library's ray queries (`prism::query`) on
//! NumPy arrays. Coordinates come in as C-contiguous (N, 3) float64 or
//! float32 arrays read in place (the package `prism` makes other layouts
//! contiguous first). Nearest hits are written into arrays kept for
//! reuse (see `recycle`); other answers go out as NumPy arrays
//! that take over the library's vectors without a copy. A long query runs
//! on a thread of its own while the caller waits without the GIL, taking
//! it every 50 ms to let Python handle signals: Ctrl-C raises the cancel
//! flag and the query stops at its next batch of rays.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, RwLock, mpsc};
use std::time::Duration;

use glam::DMat4;
use numpy::ndarray::{Ix1, Ix2};
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use prism::limits;
use prism::query::{Coordinates, HitsMut, QueryError, QueryOptions, RayScene as Scene, Rays};
use prism::scene::LoadOptions;
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::recycle;

/// Queries of this many rays or points or fewer run on the calling thread
/// (without the GIL, but without checking for signals): a thread of their
/// own would cost more than they take.
const SMALL: usize = 4096;

/// Meshes for exact ray queries (see `prism.RayScene`).
#[pyclass(module = "prism._prism", name = "RayScene", frozen)]
pub struct RayScene {
    /// The scene queries read: replaced whole (copy on write) when a mesh
    /// is added, so a query never waits on a build.
    scene: RwLock<Arc<Scene>>,
    /// Serialises adding meshes.
    adding: Mutex<()>,
}

impl RayScene {
    /// The scene queries read now (callable with or without the GIL).
    fn current(&self) -> PyResult<Arc<Scene>> {
        self.scene
            .read()
            .map(|s| Arc::clone(&s))
            .map_err(|_| poisoned())
    }

    /// Checks a query's rays (`origins`, `directions`, `tmin`, `tmax`,
    /// `threads`, each error naming its argument; the coordinates on the
    /// query's workers, [`Rays::deferred`]) and runs `job` on them without
    /// the GIL (see [`run`]).
    #[allow(clippy::too_many_arguments)]
    fn query_rays<'py, T: Send>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f64,
        tmax: f64,
        threads: Option<i64>,
        job: impl FnOnce(&Scene, &Rays, &QueryOptions) -> Result<T, QueryError> + Send,
    ) -> PyResult<(T, usize)> {
        let scene = self.current()?;
        let (o, d) = (
            Coords::of("origins", origins)?,
            Coords::of("directions", directions)?,
        );
        // The coordinates are checked by the query's workers, chunk by
        // chunk, not here before the work is shared.
        let rays = Rays::deferred_from_coordinates(o.coordinates()?, d.coordinates()?, tmin, tmax)
            .map_err(query_error)?;
        let threads = match threads_arg(threads) {
            Ok(t) => t,
            Err(e) => {
                // A bad ray is reported before a bad thread count.
                Rays::from_coordinates(o.coordinates()?, d.coordinates()?, tmin, tmax)
                    .map_err(query_error)?;
                return Err(e);
            }
        };
        let n = rays.len();
        let answer = run(py, n, threads, |options| job(&scene, &rays, options))?;
        Ok((answer, n))
    }
}

#[pymethods]
impl RayScene {
    #[new]
    fn new() -> Self {
        RayScene {
            scene: RwLock::new(Arc::new(Scene::new())),
            adding: Mutex::new(()),
        }
    }

    /// Adds a mesh: `vertices` (V, 3) float64/float32, `faces` (F, 3)
    /// int64, `transform` None or a (4, 4) float64 affine matrix. Returns
    /// the mesh id.
    #[pyo3(signature = (vertices, faces, transform=None))]
    fn add_mesh(
        &self,
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        transform: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u32> {
        let vertices = Coords::of("vertices", vertices)?;
        let vertices = vertices.coordinates()?;
        let faces = face_indices(faces, vertices.len() / 3)?;
        let transform = transform.map(matrix).transpose()?;
        py.detach(|| {
            let _adding = self.adding.lock().map_err(|_| poisoned())?;
            let mut scene = Scene::clone(self.current()?.as_ref());
            let id = scene
                .add_mesh(vertices, &faces, transform)
                .map_err(query_error)?;
            *self.scene.write().map_err(|_| poisoned())? = Arc::new(scene);
            Ok(id)
        })
    }

    /// Adds every mesh of a model file (OBJ, PLY, glTF/GLB) as Prism's
    /// scenes read it, under the same read policy (`allow_read`: further
    /// folders it may read). Returns the new mesh ids.
    #[pyo3(signature = (path, allow_read=Vec::new()))]
    fn add_file(
        &self,
        py: Python<'_>,
        path: PathBuf,
        allow_read: Vec<PathBuf>,
    ) -> PyResult<Vec<u32>> {
        let options = LoadOptions::with_allow_read(&allow_read, limits::DEFAULT_TEXTURE_MIB)
            .map_err(|e| PyValueError::new_err(format!("allow_read: {e}")))?;
        py.detach(|| {
            let _adding = self.adding.lock().map_err(|_| poisoned())?;
            let mut scene = Scene::clone(self.current()?.as_ref());
            let ids = scene.add_file(&path, &options).map_err(query_error)?;
            *self.scene.write().map_err(|_| poisoned())? = Arc::new(scene);
            Ok(ids)
        })
    }

    /// Number of meshes.
    #[getter]
    fn mesh_count(&self) -> PyResult<usize> {
        Ok(self.current()?.mesh_count())
    }

    /// Number of triangles (a mesh placed twice counted twice).
    #[getter]
    fn triangle_count(&self) -> PyResult<usize> {
        Ok(self.current()?.triangle_count())
    }

    /// Heap memory of the meshes and their trees, in bytes.
    #[getter]
    fn memory_bytes(&self) -> PyResult<usize> {
        Ok(self.current()?.memory_bytes())
    }

    /// Whether mesh `mesh_id` is closed (what `contains` needs).
    fn is_closed(&self, py: Python<'_>, mesh_id: u32) -> PyResult<bool> {
        let scene = self.current()?;
        py.detach(|| scene.is_closed(mesh_id))
            .ok_or_else(|| PyValueError::new_err(format!("mesh_id: no mesh {mesh_id}")))
    }

    /// The nearest hits as a dict of arrays: t, mesh_id, triangle_id, u,
    /// v, normal.
    #[pyo3(signature = (origins, directions, tmin=0.0, tmax=f64::INFINITY, threads=None))]
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f64,
        tmax: f64,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        // The answers go into arrays reused once let go (see `recycle`),
        // of the size the origins' rows give.
        let n = Coords::of("origins", origins)?.rows();
        let arrays = [
            recycle::array::<f64, _>(py, Ix1(n)),
            recycle::array::<f64, _>(py, Ix1(n)),
            recycle::array::<f64, _>(py, Ix1(n)),
        ];
        let ids = [
            recycle::array::<i64, _>(py, Ix1(n)),
            recycle::array::<i64, _>(py, Ix1(n)),
        ];
        let normal = recycle::array::<f64, _>(py, Ix2(n, 3));
        {
            let borrow = |e: numpy::BorrowError| PyRuntimeError::new_err(e.to_string());
            let slice = |e: numpy::NotContiguousError| PyRuntimeError::new_err(e.to_string());
            let [t, u, v] = arrays.each_ref().map(|a| a.try_readwrite());
            let [mesh_id, triangle_id] = ids.each_ref().map(|a| a.try_readwrite());
            let (mut t, mut u, mut v) =
                (t.map_err(borrow)?, u.map_err(borrow)?, v.map_err(borrow)?);
            let mut mesh_id = mesh_id.map_err(borrow)?;
            let mut triangle_id = triangle_id.map_err(borrow)?;
            let mut normal = normal.try_readwrite().map_err(borrow)?;
            let out = HitsMut {
                t: t.as_slice_mut().map_err(slice)?,
                mesh_id: mesh_id.as_slice_mut().map_err(slice)?,
                triangle_id: triangle_id.as_slice_mut().map_err(slice)?,
                u: u.as_slice_mut().map_err(slice)?,
                v: v.as_slice_mut().map_err(slice)?,
                normal: normal.as_slice_mut().map_err(slice)?,
            };
            self.query_rays(
                py,
                origins,
                directions,
                tmin,
                tmax,
                threads,
                move |scene, rays, options| scene.intersect_into(rays, out, options),
            )?;
        }
        let [t, u, v] = arrays;
        let [mesh_id, triangle_id] = ids;
        let out = PyDict::new(py);
        out.set_item("t", &t)?;
        out.set_item("mesh_id", &mesh_id)?;
        out.set_item("triangle_id", &triangle_id)?;
        out.set_item("u", &u)?;
        out.set_item("v", &v)?;
        out.set_item("normal", &normal)?;
        recycle::keep([
            t.into_any(),
            mesh_id.into_any(),
            triangle_id.into_any(),
            u.into_any(),
            v.into_any(),
            normal.into_any(),
        ]);
        Ok(out)
    }

    /// Whether each ray hits anything, as a bool array.
    #[pyo3(signature = (origins, directions, tmin=0.0, tmax=f64::INFINITY, threads=None))]
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f64,
        tmax: f64,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (blocked, _) = self.query_rays(
            py,
            origins,
            directions,
            tmin,
            tmax,
            threads,
            |scene, rays, options| scene.occluded(rays, options),
        )?;
        Ok(blocked.into_pyarray(py).into_any())
    }

    /// How many triangles each ray hits, as a uint32 array.
    #[pyo3(signature = (origins, directions, tmin=0.0, tmax=f64::INFINITY, threads=None))]
    fn count_intersections<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f64,
        tmax: f64,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (counts, _) = self.query_rays(
            py,
            origins,
            directions,
            tmin,
            tmax,
            threads,
            |scene, rays, options| scene.count_intersections(rays, options),
        )?;
        Ok(counts.into_pyarray(py).into_any())
    }

    /// Every hit of each ray, sorted by t, as a dict of flat arrays with
    /// per-ray offsets: offsets, t, mesh_id, triangle_id, u, v.
    #[pyo3(signature = (origins, directions, tmin=0.0, tmax=f64::INFINITY, threads=None))]
    fn all_intersections<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f64,
        tmax: f64,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (all, _) = self.query_rays(
            py,
            origins,
            directions,
            tmin,
            tmax,
            threads,
            |scene, rays, options| scene.all_intersections(rays, options),
        )?;
        let out = PyDict::new(py);
        out.set_item("offsets", all.offsets.into_pyarray(py))?;
        out.set_item("t", all.t.into_pyarray(py))?;
        out.set_item("mesh_id", all.mesh_id.into_pyarray(py))?;
        out.set_item("triangle_id", all.triangle_id.into_pyarray(py))?;
        out.set_item("u", all.u.into_pyarray(py))?;
        out.set_item("v", all.v.into_pyarray(py))?;
        Ok(out)
    }

    /// Whether each point is inside a (closed) mesh, as a bool array.
    #[pyo3(signature = (points, threads=None))]
    fn contains<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let scene = self.current()?;
        let p = Coords::of("points", points)?;
        let p = p.coordinates()?;
        let inside = run(py, p.len() / 3, threads_arg(threads)?, |options| {
            scene.contains(p, options)
        })?;
        Ok(inside.into_pyarray(py).into_any())
    }

    /// The nearest surface point to each point, as a dict of arrays:
    /// point (N×3), distance, mesh_id, triangle_id, u, v, normal (N×3).
    #[pyo3(signature = (points, threads=None))]
    fn closest_point<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let scene = self.current()?;
        let p = Coords::of("points", points)?;
        let p = p.coordinates()?;
        let near = run(py, p.len() / 3, threads_arg(threads)?, |options| {
            scene.closest_point(p, options)
        })?;
        let n = near.distance.len();
        let rows = |v: Vec<f64>| {
            numpy::ndarray::Array2::from_shape_vec((n, 3), v)
                .map_err(|e| PyRuntimeError::new_err(e.to_string()))
        };
        let (point, normal) = (rows(near.point)?, rows(near.normal)?);
        let out = PyDict::new(py);
        out.set_item("point", point.into_pyarray(py))?;
        out.set_item("distance", near.distance.into_pyarray(py))?;
        out.set_item("mesh_id", near.mesh_id.into_pyarray(py))?;
        out.set_item("triangle_id", near.triangle_id.into_pyarray(py))?;
        out.set_item("u", near.u.into_pyarray(py))?;
        out.set_item("v", near.v.into_pyarray(py))?;
        out.set_item("normal", normal.into_pyarray(py))?;
        Ok(out)
    }
}

fn poisoned() -> PyErr {
    PyRuntimeError::new_err("the ray scene was poisoned by a failed build")
}

fn query_error(e: QueryError) -> PyErr {
    match e {
        QueryError::Cancelled => PyKeyboardInterrupt::new_err("the query was cancelled"),
        other => PyValueError::new_err(other.to_string()),
    }
}

fn threads_arg(threads: Option<i64>) -> PyResult<Option<usize>> {
    match threads {
        None => Ok(None),
        Some(n) if (1..=i64::from(limits::MAX_THREADS)).contains(&n) => Ok(Some(n as usize)),
        Some(n) => Err(PyValueError::new_err(format!(
            "threads: must be between 1 and {}, got {n}",
            limits::MAX_THREADS
        ))),
    }
}

/// An (N, 3) C-contiguous coordinate array, float64 or float32, read in
/// place.
enum Coords<'py> {
    Double(&'static str, PyReadonlyArray2<'py, f64>),
    Single(&'static str, PyReadonlyArray2<'py, f32>),
}

impl<'py> Coords<'py> {
    fn of(name: &'static str, obj: &Bound<'py, PyAny>) -> PyResult<Self> {
        let shape_error = |shape: &[usize]| {
            PyValueError::new_err(format!("{name}: must have shape (N, 3), got {shape:?}"))
        };
        // Read in place only row by row (a Fortran-ordered array is
        // contiguous too, column by column).
        let layout_error = || {
            PyValueError::new_err(format!(
                "{name}: must be C-contiguous (np.ascontiguousarray)"
            ))
        };
        if let Ok(a) = obj.cast::<PyArray2<f64>>() {
            if a.shape()[1] != 3 {
                return Err(shape_error(a.shape()));
            }
            if !a.is_c_contiguous() {
                return Err(layout_error());
            }
            let a = a
                .try_readonly()
                .map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
            return Ok(Coords::Double(name, a));
        }
        if let Ok(a) = obj.cast::<PyArray2<f32>>() {
            if a.shape()[1] != 3 {
                return Err(shape_error(a.shape()));
            }
            if !a.is_c_contiguous() {
                return Err(layout_error());
            }
            let a = a
                .try_readonly()
                .map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
            return Ok(Coords::Single(name, a));
        }
        Err(PyValueError::new_err(format!(
            "{name}: must be an (N, 3) float64 or float32 NumPy array"
        )))
    }

    /// The number of rows: points or rays.
    fn rows(&self) -> usize {
        match self {
            Coords::Double(_, a) => a.shape()[0],
            Coords::Single(_, a) => a.shape()[0],
        }
    }

    /// The coordinates in place, in their own precision.
    fn coordinates(&self) -> PyResult<Coordinates<'_>> {
        let layout_error = |name: &str| {
            PyValueError::new_err(format!(
                "{name}: must be C-contiguous (np.ascontiguousarray)"
            ))
        };
        match self {
            Coords::Double(name, a) => a
                .as_slice()
                .map(Coordinates::F64)
                .map_err(|_| layout_error(name)),
            Coords::Single(name, a) => a
                .as_slice()
                .map(Coordinates::F32)
                .map_err(|_| layout_error(name)),
        }
    }
}

/// Faces as an (F, 3) int64 array, every index in 0..vertex_count.
fn face_indices(faces: &Bound<'_, PyAny>, vertex_count: usize) -> PyResult<Vec<u32>> {
    let a = faces
        .cast::<PyArray2<i64>>()
        .map_err(|_| PyValueError::new_err("faces: must be an (F, 3) integer NumPy array"))?;
    if a.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "faces: must have shape (F, 3), got {:?}",
            a.shape()
        )));
    }
    let a = a
        .try_readonly()
        .map_err(|e| PyValueError::new_err(format!("faces: {e}")))?;
    let mut out = Vec::with_capacity(a.len());
    for (i, &index) in a.as_array().iter().enumerate() {
        if index < 0 || index as u64 >= vertex_count as u64 {
            return Err(PyValueError::new_err(format!(
                "faces: row {} refers to vertex {index}, but there are {vertex_count} vertices",
                i / 3
            )));
        }
        out.push(index as u32);
    }
    Ok(out)
}

/// A (4, 4) float64 matrix, row by row as NumPy holds it.
fn matrix(obj: &Bound<'_, PyAny>) -> PyResult<DMat4> {
    let bad = || PyValueError::new_err("transform: must be a (4, 4) float64 NumPy array");
    let a = obj.cast::<PyArray2<f64>>().map_err(|_| bad())?;
    if a.shape() != [4, 4] {
        return Err(bad());
    }
    let a = a.try_readonly().map_err(|_| bad())?;
    let rows: Vec<f64> = a.as_array().iter().copied().collect();
    let mut cols = [0.0; 16];
    cols.copy_from_slice(&rows);
    Ok(DMat4::from_cols_array(&cols).transpose())
}

/// Runs `job` (a query over `count` rays or points): a small one on this
/// thread without the GIL; a large one on a thread of its own while this
/// one waits without the GIL, taking it every 50 ms to check for signals
/// (a KeyboardInterrupt raises the cancel flag, waits for the query to
/// stop, and is raised here).
fn run<T: Send>(
    py: Python<'_>,
    count: usize,
    threads: Option<usize>,
    job: impl FnOnce(&QueryOptions) -> Result<T, QueryError> + Send,
) -> PyResult<T> {
    if count <= SMALL {
        let options = QueryOptions {
            threads,
            cancel: None,
        };
        return py.detach(|| job(&options)).map_err(query_error);
    }
    let cancel = AtomicBool::new(false);
    std::thread::scope(|s| {
        let (send, receive) = mpsc::channel();
        let flag = &cancel;
        s.spawn(move || {
            let options = QueryOptions {
                threads,
                cancel: Some(flag),
            };
            let _ = send.send(job(&options));
        });
        // Waited on without the GIL, which needs a Sync handle.
        let receive = Mutex::new(receive);
        loop {
            let waited = py.detach(|| match receive.lock() {
                Ok(r) => r.recv_timeout(Duration::from_millis(50)),
                Err(_) => Err(mpsc::RecvTimeoutError::Disconnected),
            });
            match waited {
                Ok(out) => return out.map_err(query_error),
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(PyRuntimeError::new_err("the query thread failed"));
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            if let Err(e) = py.check_signals() {
                cancel.store(true, Ordering::Relaxed);
                let _ = py.detach(|| receive.lock().ok()?.recv().ok());
                return Err(e);
            }
        }
    })
}
