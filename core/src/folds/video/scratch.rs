//! Image-sized work buffers kept per thread between detection levels and frames.
//!
//! A detection level needs several buffers of the level's size (up to 1.4² times the image), a few MB each. Freshly
//! allocated, every one of their pages faults on first touch and is unmapped again on free; measured on a
//! 640x480 image, that kernel work took about a third of edge detection once the filters themselves were fast.
//! So buffers come from a small per-thread pool and go back to it when dropped. The pool is bounded (a dozen
//! buffers and 48 MB per thread); past that, buffers are simply freed.

use std::cell::RefCell;
use std::ops::{Deref, DerefMut};

/// Most buffers a thread keeps per element type.
const MAX_KEPT: usize = 12;
/// Most bytes a thread keeps per element type.
const MAX_BYTES: usize = 48 << 20;

/// Element types with a pool.
pub trait Pooled: Copy + 'static {
    #[doc(hidden)]
    fn with_pool<R>(f: impl FnOnce(&mut Vec<Vec<Self>>) -> R) -> R;
}

macro_rules! pooled {
    ($t:ty, $name:ident) => {
        thread_local! {
            static $name: RefCell<Vec<Vec<$t>>> = const { RefCell::new(Vec::new()) };
        }
        impl Pooled for $t {
            fn with_pool<R>(f: impl FnOnce(&mut Vec<Vec<Self>>) -> R) -> R {
                $name.with(|p| f(&mut p.borrow_mut()))
            }
        }
    };
}
pooled!(f32, POOL_F32);
pooled!(u8, POOL_U8);
pooled!(bool, POOL_BOOL);

/// A buffer from the current thread's pool; it returns there when dropped.
#[derive(Debug)]
pub struct Scratch<T: Pooled>(Vec<T>);

impl<T: Pooled> Scratch<T> {
    /// A buffer of `len` elements, all `value`.
    pub fn filled(len: usize, value: T) -> Self {
        let mut v = T::with_pool(|pool| {
            // The smallest buffer that fits, else the largest (it grows once).
            let fit = (0..pool.len())
                .filter(|&i| pool[i].capacity() >= len)
                .min_by_key(|&i| pool[i].capacity())
                .or_else(|| (0..pool.len()).max_by_key(|&i| pool[i].capacity()));
            fit.map(|i| pool.swap_remove(i))
        })
        .unwrap_or_default();
        v.clear();
        v.resize(len, value);
        Scratch(v)
    }

    /// The buffer as a plain vector, leaving the pool for good.
    pub fn into_vec(mut self) -> Vec<T> {
        std::mem::take(&mut self.0)
    }
}

/// Hands a vector (one that left the pool with [`Scratch::into_vec`], or any other) to the current thread's pool.
pub fn recycle<T: Pooled>(v: Vec<T>) {
    if v.capacity() == 0 {
        return;
    }
    T::with_pool(|pool| {
        let bytes: usize = pool
            .iter()
            .map(|b| b.capacity() * std::mem::size_of::<T>())
            .sum();
        if pool.len() < MAX_KEPT && bytes + v.capacity() * std::mem::size_of::<T>() <= MAX_BYTES {
            pool.push(v);
        }
    });
}

impl<T: Pooled> Drop for Scratch<T> {
    fn drop(&mut self) {
        recycle(std::mem::take(&mut self.0));
    }
}

impl<T: Pooled> Deref for Scratch<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.0
    }
}

impl<T: Pooled> DerefMut for Scratch<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_are_filled_reused_and_bounded() {
        // Runs on its own thread: the pool is per thread.
        std::thread::spawn(|| {
            let a = Scratch::filled(1000, 7.0f32);
            assert!(a.iter().all(|&v| v == 7.0));
            let ptr = a.as_ptr();
            drop(a);
            // The same allocation comes back, refilled.
            let b = Scratch::filled(800, 0.5f32);
            assert_eq!(b.as_ptr(), ptr);
            assert_eq!(b.len(), 800);
            assert!(b.iter().all(|&v| v == 0.5));
            // A buffer that left the pool does not come back on its own.
            let v = b.into_vec();
            assert_eq!(f32::with_pool(|p| p.len()), 0);
            recycle(v);
            assert_eq!(f32::with_pool(|p| p.len()), 1);
            // Never more than MAX_KEPT buffers nor MAX_BYTES.
            let many: Vec<Scratch<u8>> =
                (0..MAX_KEPT + 5).map(|_| Scratch::filled(10, 1)).collect();
            drop(many);
            assert_eq!(u8::with_pool(|p| p.len()), MAX_KEPT);
            drop(Scratch::filled(MAX_BYTES, false));
            assert_eq!(bool::with_pool(|p| p.len()), 1);
            drop((Scratch::filled(MAX_BYTES, false), Scratch::filled(10, true)));
            assert!(bool::with_pool(|p| p.iter().map(Vec::capacity).sum::<usize>()) <= MAX_BYTES);
        })
        .join()
        .unwrap();
    }
}
