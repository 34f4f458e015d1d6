//! Large zeroed buffers backed by transparent huge pages where the kernel offers them
//! (`madvise` mode): a 150 MB label volume then costs ~75 page faults instead of ~38,000,
//! which on this kind of machine is most of the time spent "allocating" it.

/// Below this, buffers are left to the allocator as they are.
const MIN_BYTES: usize = 4 << 20;

/// A vector of `n` default (all-zero) values whose pages are advised to be huge. Lazily
/// zeroed (fresh pages, advised before first touch) only for the types `vec!` allocates zeroed:
/// integers, floats and arrays of them; any other type is filled on one thread first.
pub fn zeroed_vec<T: Copy + Default>(n: usize) -> Vec<T> {
    let v = vec![T::default(); n];
    advise(&v);
    v
}

/// Types whose all-zero bytes are their default value: integers and floats.
pub trait Zeroable: Copy + Default {}
impl Zeroable for u8 {}
impl Zeroable for u16 {}
impl Zeroable for u32 {}
impl Zeroable for u64 {}
impl Zeroable for i32 {}
impl Zeroable for f32 {}
impl Zeroable for f64 {}

/// [`zeroed_vec`] that answers `None` when the memory cannot be had (a size from a file
/// header, say), instead of aborting the process.
pub fn try_zeroed_vec<T: Zeroable>(n: usize) -> Option<Vec<T>> {
    let layout = std::alloc::Layout::array::<T>(n).ok()?;
    if layout.size() == 0 {
        return Some(vec![T::default(); n]);
    }
    // SAFETY: a non-zero-size layout for `n` values of T; all-zero bytes are a valid T
    // (`Zeroable`); the buffer comes from the global allocator with exactly this layout, as
    // `Vec::from_raw_parts` requires, with length and capacity `n`.
    let v = unsafe {
        let ptr = std::alloc::alloc_zeroed(layout) as *mut T;
        if ptr.is_null() {
            return None;
        }
        Vec::from_raw_parts(ptr, n, n)
    };
    advise(&v);
    Some(v)
}

/// An empty vector with room for `n` values whose pages are advised to be huge (a buffer that
/// is written whole right away: its first touch then faults in 2 MiB at a time).
pub fn with_capacity<T>(n: usize) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    advise(v.spare_capacity_mut());
    v
}

/// Asks for huge pages over the 2 MiB-aligned interior of `v`'s buffer (before it is touched).
/// A hint only: nothing changes where the kernel does not support it.
pub fn advise<T>(v: &[T]) {
    let bytes = std::mem::size_of_val(v);
    if bytes < MIN_BYTES {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let start = v.as_ptr() as usize;
        let aligned = start.next_multiple_of(HUGE);
        let end = (start + bytes) & !(HUGE - 1);
        if end > aligned {
            // SAFETY: the range lies inside `v`'s allocation; MADV_HUGEPAGE changes no
            // contents, only how future faults are served.
            unsafe {
                libc::madvise(
                    aligned as *mut libc::c_void,
                    end - aligned,
                    libc::MADV_HUGEPAGE,
                );
            }
        }
    }
}
