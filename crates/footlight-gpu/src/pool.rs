//! Book-keeping for the GPU tile pool: which tile slots of which page are free.
//!
//! The pool is a list of pages, each one storage buffer of whole tiles, at
//! most the device's binding limit. A light's tiles go into runs of
//! consecutive free slots (first fit, lowest page and slot first), so a light
//! uploads with one `write_buffer` per run, usually one. Runs may span free
//! ranges and pages, so a light never needs contiguous space and freeing
//! never leaves space that cannot be used. Pure CPU state, unit-tested here;
//! the compositor owns the buffers and grows them when [`TileAllocator::alloc`]
//! finds too little space.

use std::ops::Range;

/// Consecutive pool slots holding consecutive tiles of one light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Run {
    /// Page index.
    pub page: u32,
    /// First slot in the page.
    pub start: u32,
    /// Slots.
    pub len: u32,
}

#[derive(Debug)]
struct Page {
    capacity: u32,
    /// Free slot ranges, sorted, disjoint, never adjacent (merged).
    free: Vec<Range<u32>>,
}

/// Free-slot lists of the pool's pages.
#[derive(Debug, Default)]
pub(crate) struct TileAllocator {
    pages: Vec<Page>,
}

impl TileAllocator {
    /// Number of pages.
    pub fn pages(&self) -> usize {
        self.pages.len()
    }

    /// Capacity of `page` in tiles.
    pub fn capacity(&self, page: usize) -> u32 {
        self.pages[page].capacity
    }

    /// Free slots over all pages.
    pub fn free_tiles(&self) -> u64 {
        self.pages.iter().flat_map(|p| &p.free).map(|r| u64::from(r.end - r.start)).sum()
    }

    /// Slots in use over all pages.
    pub fn used_tiles(&self) -> u64 {
        self.pages.iter().map(|p| u64::from(p.capacity)).sum::<u64>() - self.free_tiles()
    }

    /// Adds an empty page of `capacity` slots.
    pub fn add_page(&mut self, capacity: u32) {
        let mut free = Vec::new();
        if capacity > 0 {
            free.push(0..capacity);
        }
        self.pages.push(Page { capacity, free });
    }

    /// Grows the last page to `capacity` slots (the caller has copied its
    /// contents into a bigger buffer).
    pub fn grow_last(&mut self, capacity: u32) {
        let page = self.pages.last_mut().expect("grow_last without a page");
        assert!(capacity >= page.capacity, "pages only grow");
        let added = page.capacity..capacity;
        page.capacity = capacity;
        if !added.is_empty() {
            Self::insert_free(&mut page.free, added);
        }
    }

    /// Takes `n` slots, lowest first, as runs; `None` (and nothing taken)
    /// when fewer than `n` are free.
    pub fn alloc(&mut self, n: u32) -> Option<Vec<Run>> {
        if u64::from(n) > self.free_tiles() {
            return None;
        }
        let mut runs = Vec::new();
        let mut left = n;
        for (p, page) in self.pages.iter_mut().enumerate() {
            while left > 0 && !page.free.is_empty() {
                let r = &mut page.free[0];
                let take = left.min(r.end - r.start);
                runs.push(Run { page: p as u32, start: r.start, len: take });
                r.start += take;
                left -= take;
                if r.start == r.end {
                    page.free.remove(0);
                }
            }
            if left == 0 {
                break;
            }
        }
        Some(runs)
    }

    /// Returns runs to the free lists.
    pub fn free(&mut self, runs: &[Run]) {
        for run in runs.iter().filter(|r| r.len > 0) {
            let page = &mut self.pages[run.page as usize];
            debug_assert!(run.start + run.len <= page.capacity, "run past its page");
            Self::insert_free(&mut page.free, run.start..run.start + run.len);
        }
    }

    /// Inserts `r` into a sorted free list, merging with its neighbours.
    fn insert_free(free: &mut Vec<Range<u32>>, r: Range<u32>) {
        let i = free.partition_point(|f| f.start < r.start);
        debug_assert!(i == 0 || free[i - 1].end <= r.start, "double free");
        debug_assert!(i == free.len() || r.end <= free[i].start, "double free");
        let joins_prev = i > 0 && free[i - 1].end == r.start;
        let joins_next = i < free.len() && free[i].start == r.end;
        match (joins_prev, joins_next) {
            (true, true) => {
                free[i - 1].end = free[i].end;
                free.remove(i);
            }
            (true, false) => free[i - 1].end = r.end,
            (false, true) => free[i].start = r.start,
            (false, false) => free.insert(i, r),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allocates_lowest_first_and_merges_freed_space() {
        let mut a = TileAllocator::default();
        a.add_page(10);
        let x = a.alloc(4).unwrap();
        let y = a.alloc(3).unwrap();
        assert_eq!(x, vec![Run { page: 0, start: 0, len: 4 }]);
        assert_eq!(y, vec![Run { page: 0, start: 4, len: 3 }]);
        assert!(a.alloc(4).is_none(), "3 free, nothing taken on failure");
        assert_eq!(a.free_tiles(), 3);
        a.free(&x);
        // Fragmented: 0..4 and 7..10 free; a request of 6 spans both.
        let z = a.alloc(6).unwrap();
        assert_eq!(z, vec![Run { page: 0, start: 0, len: 4 }, Run { page: 0, start: 7, len: 2 }]);
        a.free(&y);
        a.free(&z);
        assert_eq!(a.free_tiles(), 10);
        assert_eq!(a.alloc(10).unwrap(), vec![Run { page: 0, start: 0, len: 10 }], "fully merged");
    }

    #[test]
    fn grows_the_last_page_and_spans_pages() {
        let mut a = TileAllocator::default();
        a.add_page(4);
        let x = a.alloc(3).unwrap();
        a.grow_last(8);
        assert_eq!(a.free_tiles(), 5);
        a.add_page(2);
        let y = a.alloc(7).unwrap();
        assert_eq!(y, vec![Run { page: 0, start: 3, len: 5 }, Run { page: 1, start: 0, len: 2 }]);
        assert_eq!(a.used_tiles(), 10);
        a.free(&x);
        a.free(&y);
        assert_eq!(a.used_tiles(), 0);
        assert_eq!((a.pages(), a.capacity(0), a.capacity(1)), (2, 8, 2));
    }

    #[test]
    fn zero_tiles_take_nothing() {
        let mut a = TileAllocator::default();
        assert_eq!(a.alloc(0), Some(vec![]));
        a.add_page(0);
        assert_eq!(a.alloc(0), Some(vec![]));
        assert!(a.alloc(1).is_none());
    }
}
