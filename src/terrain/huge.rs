//! Large arrays on huge pages where the kernel grants them, and the
//! page-level care of sparse arrays and large mappings.
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

/// `len` zeros, or `None` where the allocator cannot give the address
/// space: zeroed memory straight from the allocator (no page touched until
/// written), for a sparse level the size of a map larger than memory,
/// whose failure must be an error rather than an abort.
pub fn try_zeroed<T: ZeroIsValid>(len: usize) -> Option<Vec<T>> {
    let layout = std::alloc::Layout::array::<T>(len).ok()?;
    if layout.size() == 0 {
        return Some(Vec::new());
    }
    // SAFETY: a non-zero layout; the memory is the global allocator's,
    // zeroed, and all-zero bytes are a valid `T` (`ZeroIsValid`), so a Vec
    // of `len` initialised elements may own it.
    unsafe {
        let p = std::alloc::alloc_zeroed(layout) as *mut T;
        (!p.is_null()).then(|| Vec::from_raw_parts(p, len, len))
    }
}

/// Types whose all-zero bytes are a valid value (0.0, false), which
/// [`release`] may leave in their place.
pub trait ZeroIsValid: Copy {}
impl ZeroIsValid for f32 {}
impl ZeroIsValid for bool {}

/// The whole 4 KB pages inside `s`, as (start, bytes), if any.
#[cfg(target_os = "linux")]
fn inner_pages<T>(s: &[T]) -> Option<(usize, usize)> {
    const PAGE: usize = 4096;
    let a = (s.as_ptr() as usize).next_multiple_of(PAGE);
    let b = (s.as_ptr() as usize + std::mem::size_of_val(s)) / PAGE * PAGE;
    (b > a).then(|| (a, b - a))
}

/// Keeps `s` on small pages even where transparent huge pages are
/// `always`: for a large array filled sparsely (a decoded pack's levels),
/// whose every touched sample would otherwise make 2 MB resident.
pub fn small_pages<T>(s: &mut [T]) {
    #[cfg(target_os = "linux")]
    if let Some((start, bytes)) = inner_pages(s) {
        // SAFETY: the range lies inside `s`; the advice changes how its
        // pages are backed, never their contents.
        unsafe {
            libc::madvise(start as *mut libc::c_void, bytes, libc::MADV_NOHUGEPAGE);
        }
    }
}

/// Gives the whole pages inside `s` back to the kernel: they read as
/// zeros afterwards, and are no longer resident. For samples a sparse
/// level no longer holds (tiles evicted), where zero is any value's
/// stand-in until they are written again. Where not Linux, nothing is
/// given back (the values stay).
pub fn release<T: ZeroIsValid>(s: &mut [T]) {
    #[cfg(target_os = "linux")]
    if let Some((start, bytes)) = inner_pages(s) {
        // SAFETY: the range lies inside `s`, which this call borrows
        // mutably; the kernel refills private anonymous pages with zeros,
        // a valid value of every `ZeroIsValid` type.
        unsafe {
            libc::madvise(start as *mut libc::c_void, bytes, libc::MADV_DONTNEED);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = s;
}

/// Drops the pages of bytes `range` of a read-only file mapping from this
/// process (they stay in the page cache): a reader that goes through a
/// large file once keeps its resident memory to what it is reading.
pub fn drop_mapped(map: &memmap2::Mmap, range: std::ops::Range<usize>) {
    const PAGE: usize = 4096;
    let start = range.start / PAGE * PAGE;
    let end = range.end.min(map.len());
    if end > start {
        // SAFETY: a read-only private mapping of a file: dropped pages are
        // read from the file again if touched, with the same contents.
        let _ = unsafe {
            map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, start, end - start)
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exactly the samples in whole pages inside the slice read zero
    /// afterwards; the others, and a slice holding no whole page, keep
    /// their values.
    #[test]
    fn try_zeroed_gives_zeros_or_none() {
        let v: Vec<f32> = try_zeroed(100_000).unwrap();
        assert!(v.len() == 100_000 && v.iter().all(|&x| x == 0.0));
        assert!(try_zeroed::<bool>(0).unwrap().is_empty());
        assert!(try_zeroed::<f32>(usize::MAX / 2).is_none());
        // 128 TB: a valid layout no allocator here can give (black_box, so
        // the optimiser cannot assume an unused allocation succeeded).
        let huge = std::hint::black_box(try_zeroed::<f32>(std::hint::black_box(1 << 45)));
        assert!(huge.is_none());
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn release_zeroes_the_whole_pages_inside_only() {
        let mut v: Vec<f32> = (0..20_000).map(|i| i as f32 + 1.0).collect();
        release(&mut v[5..700]);
        assert!(v.iter().enumerate().all(|(i, &x)| x == i as f32 + 1.0));
        release(&mut v[100..9000]);
        let at = |i: usize| v.as_ptr() as usize + 4 * i;
        let (a, b) = (at(100).next_multiple_of(4096), at(9000) / 4096 * 4096);
        assert!(b - a >= 2 * 4096);
        for (i, &x) in v.iter().enumerate() {
            let gone = (a..b).contains(&at(i));
            assert_eq!(x, if gone { 0.0 } else { i as f32 + 1.0 }, "sample {i}");
        }
    }

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
