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
