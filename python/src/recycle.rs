//! Answer arrays a ray scene keeps to write later answers into.
//!
//! A million rays' nearest hits are 64 MB of arrays. Memory new to the
//! process is faulted in at its first write, and the C allocator gives
//! freed blocks that large back to the system, so a query that wrote
//! into new arrays every time spent as long in the kernel as in its
//! search (in a loop of 1M-ray queries on the 940k-triangle bunny, 75–87
//! ms of user time and 97–120 ms of system time each).
//!
//! So the arrays a query returns are also kept here, the last [`KEEP`].
//! A later query takes one of the shape it needs once nothing else holds
//! it (its reference count is this list's alone): the caller has dropped
//! it, and no view, memoryview or other array refers to it. Every entry is
//! written by the query, so what it held before does not matter. Arrays
//! still in use are never taken, and a kept array costs memory only once
//! its caller has let it go.

use std::collections::VecDeque;
use std::sync::Mutex;

use numpy::ndarray::Dimension;
use numpy::{Element, PyArray, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Arrays kept at most: two nearest-hit queries' six, and a few more.
const KEEP: usize = 16;

/// The arrays of a scene's last answers, oldest first.
#[derive(Default)]
pub struct Recycled {
    kept: Mutex<VecDeque<Py<PyAny>>>,
}

impl Recycled {
    /// A writeable, C-contiguous array of `shape`: a kept one nothing else
    /// holds (taken off the list), else a new one of zeros.
    pub fn array<'py, T: Element, D: Dimension>(
        &self,
        py: Python<'py>,
        shape: D,
    ) -> Bound<'py, PyArray<T, D>> {
        let Ok(mut kept) = self.kept.lock() else {
            return PyArray::zeros(py, shape, false);
        };
        let free = kept.iter().position(|a| {
            a.get_refcnt(py) == 1
                && a.bind(py).cast::<PyArray<T, D>>().is_ok_and(|a| {
                    a.shape() == shape.slice() && a.is_c_contiguous() && a.try_readwrite().is_ok()
                })
        });
        match free.and_then(|i| kept.remove(i)) {
            Some(a) => match a.into_bound(py).cast_into::<PyArray<T, D>>() {
                Ok(a) => a,
                Err(_) => PyArray::zeros(py, shape, false),
            },
            None => PyArray::zeros(py, shape, false),
        }
    }

    /// Keeps `arrays` (a query's answers, now the caller's too), letting
    /// the oldest go beyond [`KEEP`].
    pub fn keep<'py>(&self, arrays: impl IntoIterator<Item = Bound<'py, PyAny>>) {
        let Ok(mut kept) = self.kept.lock() else {
            return;
        };
        for a in arrays {
            kept.push_back(a.unbind());
        }
        while kept.len() > KEEP {
            kept.pop_front();
        }
    }
}
