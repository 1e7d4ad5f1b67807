//! Large arrays on huge pages where the kernel grants them.
//!
//! A pyramid level of a 32768-wide map has a 4 KB page per 1,024 texels of
//! a row, so reading down a column, or a window's rows, misses the TLB on
//! every row, and each miss walks page tables that are themselves out of
//! cache. Asking for 2 MB pages (`MADV_HUGEPAGE`, honoured where
//! transparent huge pages are `madvise` or `always`) makes a whole
//! window's rows a handful of TLB entries. A hint only: where it is not
//! granted, or not Linux, the array is the same, on small pages.

/// Arrays smaller than this stay on small pages (a 2 MB page would be
/// mostly empty, and a huge page's first touch zeroes all of it).
const MIN_BYTES: usize = 4 << 20;

/// `len` copies of `value` in memory advised for huge pages before its
/// first touch (advice given after the pages exist only applies when the
/// kernel collapses them later, if ever).
pub fn filled<T: Copy>(len: usize, value: T) -> Vec<T> {
    collect(std::iter::repeat_n(value, len))
}

/// The items of `iter` in memory advised like [`filled`]'s: each texel is
/// written once, where filling first and then overwriting wrote a large
/// map twice.
pub fn collect<T, I: ExactSizeIterator<Item = T>>(iter: I) -> Vec<T> {
    let mut v = Vec::with_capacity(iter.len());
    advise(
        v.as_mut_ptr() as *mut u8,
        iter.len() * std::mem::size_of::<T>(),
    );
    v.extend(iter);
    v
}

#[cfg(target_os = "linux")]
fn advise(ptr: *mut u8, bytes: usize) {
    const HUGE: usize = 2 << 20;
    if bytes < MIN_BYTES {
        return;
    }
    // The 2 MB-aligned interior: madvise needs a page-aligned start, and
    // only aligned 2 MB extents can be huge pages.
    let start = (ptr as usize).next_multiple_of(HUGE);
    let end = (ptr as usize + bytes) / HUGE * HUGE;
    if end > start {
        // SAFETY: the range lies inside this Vec's own allocation; the
        // advice changes how its pages are backed, never their contents.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_ptr: *mut u8, _bytes: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filled_holds_the_value_on_small_and_huge_pages() {
        // Below the threshold, and large enough to hold aligned 2 MB extents.
        for len in [0usize, 1, 1000, (MIN_BYTES / 4) * 3 + 17] {
            let v = filled(len, 2.5f32);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|&x| x.to_bits() == 2.5f32.to_bits()));
        }
        let b = filled(MIN_BYTES + 3, true);
        assert!(b.iter().all(|&x| x));
        let n = MIN_BYTES / 4 * 3 + 17;
        let c = collect((0..n).map(|i| i as u32));
        assert!(c.len() == n && c.iter().enumerate().all(|(i, &x)| x == i as u32));
    }
}
