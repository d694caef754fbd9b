//! Sparse node sets of the octree levels: a bitmap over the full grid of a level with a rank
//! index, so that "is this node present, and what is its slot" costs one popcount.
//!
//! A level-`d` grid has `2^d + 1` nodes per axis over the unit cube. At depth 10 the bitmap of
//! the full grid is 135 MB; depth 9, the default, needs 17 MB: far less than a hash map of the
//! few million nodes near the surface would. The extraction (`contour`) uses the same
//! structure over the grid's cells to number the cells the surface crosses.

/// The deepest octree level supported: the bitmap of its node grid takes 135 MB.
pub(crate) const MAX_DEPTH: u32 = 10;

/// A set of nodes of one level's grid, with a dense slot (rank) per present node.
#[derive(Debug, Clone)]
pub(crate) struct NodeSet {
    /// Nodes per axis, `2^d + 1`.
    pub(crate) n: usize,
    bits: Vec<u64>,
    /// Number of set bits before each word.
    prefix: Vec<u32>,
    /// Linear ids (`(z * n + y) * n + x`) of the present nodes, in slot order.
    pub(crate) ids: Vec<u64>,
}

impl NodeSet {
    /// An empty set over a grid of `n` nodes per axis.
    pub(crate) fn empty(n: usize) -> Self {
        let words = (n * n * n).div_ceil(64);
        Self {
            n,
            bits: vec![0; words],
            prefix: Vec::new(),
            ids: Vec::new(),
        }
    }

    /// Marks node `(x, y, z)` (must be inside the grid).
    #[inline]
    pub(crate) fn insert(&mut self, x: usize, y: usize, z: usize) {
        let id = (z * self.n + y) * self.n + x;
        self.bits[id >> 6] |= 1 << (id & 63);
    }

    /// Marks every node of the grid.
    pub(crate) fn fill(&mut self) {
        let total = self.n * self.n * self.n;
        for (w, word) in self.bits.iter_mut().enumerate() {
            let left = total - w * 64;
            *word = if left >= 64 {
                u64::MAX
            } else {
                (1 << left) - 1
            };
        }
    }

    /// Builds the rank index and the slot list; call once after the last insertion.
    pub(crate) fn finish(&mut self) {
        self.prefix = Vec::with_capacity(self.bits.len());
        self.ids.clear();
        let mut count = 0u32;
        for (w, &word) in self.bits.iter().enumerate() {
            self.prefix.push(count);
            count += word.count_ones();
            let mut b = word;
            while b != 0 {
                let t = b.trailing_zeros() as u64;
                self.ids.push(w as u64 * 64 + t);
                b &= b - 1;
            }
        }
    }

    /// Number of present nodes.
    pub(crate) fn len(&self) -> usize {
        self.ids.len()
    }

    /// The slot of node `(x, y, z)`, or `None` when absent (coordinates may be out of the grid).
    #[inline]
    pub(crate) fn slot(&self, x: i64, y: i64, z: i64) -> Option<u32> {
        let n = self.n as i64;
        if x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n {
            return None;
        }
        self.slot_of_id(((z * n + y) * n + x) as u64)
    }

    /// The slot of the node with linear id `id` (inside the grid), or `None` when absent.
    #[inline]
    pub(crate) fn slot_of_id(&self, id: u64) -> Option<u32> {
        let w = (id >> 6) as usize;
        let word = self.bits[w];
        let bit = 1u64 << (id & 63);
        (word & bit != 0).then(|| self.prefix[w] + (word & (bit - 1)).count_ones())
    }

    /// Coordinates of the node in `slot`.
    #[inline]
    pub(crate) fn coords(&self, slot: usize) -> [i64; 3] {
        let id = self.ids[slot] as usize;
        let n = self.n;
        [
            (id % n) as i64,
            ((id / n) % n) as i64,
            (id / (n * n)) as i64,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_matches_insertion_order() {
        let mut s = NodeSet::empty(9);
        let pts = [(0, 0, 0), (8, 8, 8), (3, 4, 5), (7, 0, 1), (1, 2, 3)];
        for &(x, y, z) in &pts {
            s.insert(x, y, z);
        }
        s.finish();
        assert_eq!(s.len(), pts.len());
        for &(x, y, z) in &pts {
            let slot = s.slot(x as i64, y as i64, z as i64).unwrap() as usize;
            assert_eq!(s.coords(slot), [x as i64, y as i64, z as i64]);
        }
        assert_eq!(s.slot(2, 2, 2), None);
        assert_eq!(s.slot(-1, 0, 0), None);
        assert_eq!(s.slot(9, 0, 0), None);
        let mut f = NodeSet::empty(5);
        f.fill();
        f.finish();
        assert_eq!(f.len(), 125);
        assert_eq!(f.slot(4, 4, 4), Some(124));
    }
}
