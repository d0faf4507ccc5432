//! The pattern of a symmetry reduction: a model's rows onto its classes' orbits
//! ([`super::mirrors::Mirrors::reduce`]), a class's onto its halves' pairs of orbits
//! ([`super::split::Split::reduce`]).
//!
//! A reduced problem's block `(r, s)` sums the blocks of the representative row of `r` whose
//! columns fall in `s`. Which blocks those are does not depend on the class (its signs and
//! weights do), so the pattern and each block's target are worked out once per model (and
//! once per swap that splits) and every class's sums read them.

use crate::fem::sparse::BlockPattern;

/// The pattern of a reduction (a model's onto its classes', a class's onto its halves') and
/// where each block of the representatives' rows is summed. Every class of a model has the
/// same pattern over its orbits (the classes' DOFs differ, not their blocks), and so have
/// the halves of the classes one swap splits: it is worked out by the first reduction and
/// read by the others'.
pub(super) struct ReducedPattern {
    pub(super) pattern: BlockPattern,
    /// The reduced block each block of the representatives' rows is summed into, row by row.
    pub(super) target: Vec<u32>,
    /// Each reduced node's diagonal block and its representative's in the pattern reduced.
    pub(super) diagonal: Vec<(u32, u32)>,
}

impl ReducedPattern {
    /// The reduction of `p`'s rows `reps` (reduced node `r` from row `reps[r]`), column `q`
    /// going to reduced node `node_of(q)` (so `node_of(reps[r]) = r`).
    pub(super) fn new(p: &BlockPattern, reps: &[usize], node_of: impl Fn(usize) -> u32) -> Self {
        let nodes = reps.len();
        // The representatives' rows bound the reduced rows' lengths (nodes merge columns):
        // reserved once, the growing rows are not copied by reallocation.
        let bound: usize = reps.iter().map(|&r| p.row_ptr[r + 1] - p.row_ptr[r]).sum();
        let mut row_ptr = Vec::with_capacity(nodes + 1);
        row_ptr.push(0);
        let (mut col, mut target) = (Vec::with_capacity(bound), Vec::with_capacity(bound));
        let mut diagonal = Vec::with_capacity(nodes);
        let mut row = ReducedRow::new(nodes);
        for &rep in reps {
            let blocks = p.row_ptr[rep]..p.row_ptr[rep + 1];
            let columns = p.col[blocks.clone()].iter();
            row.open(columns.map(|&q| node_of(q as usize)), &mut col);
            target.extend(blocks.map(|blk| row.at(node_of(p.col[blk] as usize) as usize) as u32));
            let own = p.find(rep, rep as u32).expect("diagonal block");
            diagonal.push((row.at(node_of(rep) as usize) as u32, own as u32));
            row.close();
            row_ptr.push(col.len());
        }
        ReducedPattern {
            pattern: BlockPattern { row_ptr, col },
            target,
            diagonal,
        }
    }
}

/// Where each column of the reduced row being built sits, for a reduction that sums the
/// blocks of several original columns into one (orbits of nodes, pairs of orbits).
struct ReducedRow {
    /// Block index of each reduced column in the open row; `u32::MAX` elsewhere.
    slot: Vec<u32>,
    /// The open row's reduced columns, sorted.
    cols: Vec<u32>,
}

impl ReducedRow {
    /// For reductions onto `columns` reduced columns.
    fn new(columns: usize) -> Self {
        ReducedRow {
            slot: vec![u32::MAX; columns],
            cols: Vec::new(),
        }
    }

    /// Opens the next row, whose blocks fall in the reduced columns `targets` (repeats
    /// allowed): appends them, distinct and sorted, to the pattern's `col`.
    fn open(&mut self, targets: impl Iterator<Item = u32>, col: &mut Vec<u32>) {
        self.cols.clear();
        for t in targets {
            if self.slot[t as usize] == u32::MAX {
                self.slot[t as usize] = 0;
                self.cols.push(t);
            }
        }
        self.cols.sort_unstable();
        let start = col.len();
        for (i, &t) in self.cols.iter().enumerate() {
            self.slot[t as usize] = (start + i) as u32;
        }
        col.extend_from_slice(&self.cols);
    }

    /// The block index of reduced column `t` in the open row.
    fn at(&self, t: usize) -> usize {
        self.slot[t] as usize
    }

    /// Closes the open row.
    fn close(&mut self) {
        for &t in &self.cols {
            self.slot[t as usize] = u32::MAX;
        }
    }
}
