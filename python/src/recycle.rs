//! Answer arrays kept to write later answers into.
//!
//! A million rays' nearest hits are 64 MB of arrays. Memory new to the
//! process is faulted in at its first write, and the C allocator gives
//! freed blocks that large back to the system, so a query that wrote
//! into new arrays every time spent as long in the kernel as in its
//! search (in a loop of 1M-ray queries on the 940k-triangle bunny, 75–87
//! ms of user time and 97–120 ms of system time each).
//!
//! So the arrays a query returns are also kept here, the last [`KEEP`]
//! up to [`KEEP_BYTES`], for every scene of the process (a scene built
//! anew, as a script that loads one mesh after another does, queries with
//! the same number of rays). A later query takes one of the shape it
//! needs once nothing else holds it (its reference count is this list's
//! alone): the caller has dropped it, and no view, memoryview or other
//! array refers to it. Every entry is written by the query, so what it
//! held before does not matter. Arrays still in use are never taken, and a
//! kept array costs memory only once its caller has let it go.

use std::collections::VecDeque;
use std::sync::{Mutex, PoisonError};

use numpy::ndarray::Dimension;
use numpy::{Element, PyArray, PyArrayDescrMethods, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Arrays kept at most: four nearest-hit queries' six (a caller that
/// keeps each query's answers until the next one's are back lets go of
/// them a query late).
const KEEP: usize = 24;

/// Bytes kept at most (256 MiB): four 1M-ray nearest-hit answers. A
/// larger answer is not kept.
const KEEP_BYTES: usize = 256 << 20;

/// The arrays of the last answers with their sizes in bytes, oldest first.
static KEPT: Mutex<VecDeque<(Py<PyAny>, usize)>> = Mutex::new(VecDeque::new());

/// A writeable, C-contiguous array of `shape`: a kept one nothing else
/// holds (taken off the list), else a new one of zeros.
pub fn array<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    shape: D,
) -> Bound<'py, PyArray<T, D>> {
    let mut kept = KEPT.lock().unwrap_or_else(PoisonError::into_inner);
    let free = kept.iter().position(|(a, _)| {
        a.get_refcnt(py) == 1
            && a.bind(py).cast::<PyArray<T, D>>().is_ok_and(|a| {
                a.shape() == shape.slice() && a.is_c_contiguous() && a.try_readwrite().is_ok()
            })
    });
    match free.and_then(|i| kept.remove(i)) {
        Some((a, _)) => match a.into_bound(py).cast_into::<PyArray<T, D>>() {
            Ok(a) => a,
            Err(_) => PyArray::zeros(py, shape, false),
        },
        None => PyArray::zeros(py, shape, false),
    }
}

/// Keeps `arrays` (a query's answers, now the caller's too), letting the
/// oldest go beyond [`KEEP`] arrays or [`KEEP_BYTES`].
pub fn keep<'py>(arrays: impl IntoIterator<Item = Bound<'py, PyAny>>) {
    let mut let_go = Vec::new();
    {
        let mut kept = KEPT.lock().unwrap_or_else(PoisonError::into_inner);
        for a in arrays {
            let bytes = a
                .cast::<numpy::PyUntypedArray>()
                .map_or(usize::MAX, |u| u.len().saturating_mul(u.dtype().itemsize()));
            kept.push_back((a.unbind(), bytes));
        }
        let total = |kept: &VecDeque<(Py<PyAny>, usize)>| {
            kept.iter()
                .fold(0usize, |sum, (_, b)| sum.saturating_add(*b))
        };
        while kept.len() > KEEP || total(&kept) > KEEP_BYTES {
            let_go.extend(kept.pop_front());
        }
    }
    // Released outside the lock: freeing an array runs no code of ours,
    // but nothing freed under the lock could then ever wait on it.
    drop(let_go);
}
