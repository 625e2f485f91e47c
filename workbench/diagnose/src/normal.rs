//! The empirical tables' linearised model: normal equations `J'WJ`, `J'Wr` of node
//! responses against the residual, per held-out fold and whole ([`normal`]), and the
//! same read for any set of maps from products computed once per pair of maps
//! ([`Products`]): the forward selection fits every map beside the set at every stage,
//! and summing a hundred columns' products over the samples again for each trial was
//! the table fit's largest serial cost. Read, a set's equations have the bits
//! [`normal`] computes for it.

use std::ops::Range;
use std::sync::OnceLock;

/// The linearised model over a set of columns: per fold and whole, `J'WJ` and `J'W r`.
pub(super) struct Normal {
    pub n: usize,
    pub g: Vec<f64>,
    pub b: Vec<f64>,
    pub gf: Vec<Vec<f64>>,
    pub bf: Vec<Vec<f64>>,
}

impl Normal {
    /// No columns.
    pub fn empty() -> Self {
        Self { n: 0, g: Vec::new(), b: Vec::new(), gf: Vec::new(), bf: Vec::new() }
    }

    /// The whole from the folds' parts, summed fold after fold.
    fn of_folds(n: usize, gf: Vec<Vec<f64>>, bf: Vec<Vec<f64>>) -> Self {
        let mut g = vec![0.0; n * n];
        let mut b = vec![0.0; n];
        for (gk, bk) in gf.iter().zip(&bf) {
            g.iter_mut().zip(gk).for_each(|(x, y)| *x += y);
            b.iter_mut().zip(bk).for_each(|(x, y)| *x += y);
        }
        Self { n, g, b, gf, bf }
    }
}

/// What the products are summed over: the residual `r[channel][sample]`, the weights
/// `w[channel][sample]` and the held-out fold of each sample.
#[derive(Clone, Copy)]
pub(super) struct Samples<'a> {
    pub r: &'a [Vec<f64>],
    pub w: &'a [Vec<f64>],
    pub folds: &'a [usize],
}

/// Responses `[column][channel][sample]` against the residual: `J'WJ` and `J'Wr` per fold
/// (`nf` of them) and whole. The folds are summed side by side (each in the samples'
/// order, so the same bits as one pass).
pub(super) fn normal(cols: &[&Vec<Vec<f64>>], s: Samples, nf: usize) -> Normal {
    use rayon::prelude::*;
    let n = cols.len();
    let (gf, bf): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (0..nf)
        .into_par_iter()
        .map(|f| {
            let (mut g, b) = products(cols, s, f, (0..n, 0..n), true);
            for i in 0..n {
                for j in 0..i {
                    g[i * n + j] = g[j * n + i];
                }
            }
            (g, b)
        })
        .unzip();
    Normal::of_folds(n, gf, bf)
}

/// Over the samples of fold `f`: `Σ (w a_i) a_j` for rows `i` and columns `j` of `cols`
/// (row-major, `rows.len() × cols.len()`; only `j ≥ i` when `upper`, the rest left 0),
/// and `Σ (w a_i) r`. Every element is summed over channels, then samples, in order, and
/// a sample where `a_i` is 0 adds nothing to row `i`: the same bits whichever rows and
/// columns are asked for.
fn products(
    cols: &[&Vec<Vec<f64>>],
    s: Samples,
    f: usize,
    (rows, across): (Range<usize>, Range<usize>),
    upper: bool,
) -> (Vec<f64>, Vec<f64>) {
    let width = across.len();
    let (mut g, mut b) = (vec![0.0; rows.len() * width], vec![0.0; rows.len()]);
    let mut a = vec![0.0; cols.len()];
    for (c, (rc, wc)) in s.r.iter().zip(s.w).enumerate() {
        let in_fold = rc.iter().zip(s.folds).zip(wc).enumerate().filter(|(_, ((_, k), _))| **k == f);
        for (t, ((rt, _), wc)) in in_fold {
            for k in rows.clone().chain(across.clone()) {
                a[k] = cols[k][c][t];
            }
            for (row, i) in rows.clone().enumerate() {
                if a[i] == 0.0 {
                    continue;
                }
                let wa = wc * a[i];
                b[row] += wa * rt;
                let from = if upper { i.max(across.start) } else { across.start };
                let out = &mut g[row * width..(row + 1) * width];
                for (gj, aj) in out[from - across.start..].iter_mut().zip(&a[from..across.end]) {
                    *gj += wa * aj;
                }
            }
        }
    }
    (g, b)
}

/// The products of every map's columns with every other's, computed when a set first
/// asks for them and kept: per fold, `Σ (w a_i) a_j` for the columns of map `p` against
/// those of map `q` in that order (a set taking `p` first reads `(p, q)`; the bits
/// depend on which column is taken first), `J'Wr` with each map's own block.
pub(super) struct Products<'a> {
    cols: Vec<&'a Vec<Vec<f64>>>,
    /// Where each map's columns start in `cols`, and one past the last map's end.
    start: Vec<usize>,
    s: Samples<'a>,
    nf: usize,
    /// `[p * maps + q]`: per fold, map `p`'s rows against map `q`'s columns (map `p`'s
    /// own block: upper triangle only), and map `p`'s `J'Wr`.
    blocks: Vec<OnceLock<Block>>,
}

/// Per fold: a block of products (row-major) and its rows' `J'Wr`.
type Block = (Vec<Vec<f64>>, Vec<Vec<f64>>);

impl<'a> Products<'a> {
    /// The maps' columns (`maps[map][column]`, each `[channel][sample]`) against `s`.
    pub fn new(maps: &'a [Vec<Vec<Vec<f64>>>], s: Samples<'a>, nf: usize) -> Self {
        let mut start = vec![0];
        for m in maps {
            start.push(start.last().copied().unwrap_or(0) + m.len());
        }
        let blocks = (0..maps.len() * maps.len()).map(|_| OnceLock::new()).collect();
        Self { cols: maps.iter().flatten().collect(), start, s, nf, blocks }
    }

    fn range(&self, m: usize) -> Range<usize> {
        self.start[m]..self.start[m + 1]
    }

    fn block(&self, p: usize, q: usize) -> &Block {
        self.blocks[p * (self.start.len() - 1) + q].get_or_init(|| {
            (0..self.nf)
                .map(|f| products(&self.cols, self.s, f, (self.range(p), self.range(q)), p == q))
                .unzip()
        })
    }

    /// The normal equations of the maps `set` (their columns in that order), as
    /// [`normal`] computes them on those columns.
    pub fn normal(&self, set: &[usize]) -> Normal {
        let at: Vec<usize> =
            set.iter().scan(0, |k, &m| Some(std::mem::replace(k, *k + self.range(m).len()))).collect();
        let n = set.iter().map(|&m| self.range(m).len()).sum();
        let mut gf = vec![vec![0.0; n * n]; self.nf];
        let mut bf = vec![vec![0.0; n]; self.nf];
        for (x, &p) in set.iter().enumerate() {
            for (&q, &col0) in set.iter().zip(&at).skip(x) {
                self.place(&mut gf, &mut bf, n, (p, at[x]), (q, col0));
            }
        }
        Normal::of_folds(n, gf, bf)
    }

    /// Block `(p, q)` into a set's equations (`n` columns) at rows from `r0` and columns
    /// from `c0`, mirrored; map `p`'s own block brings its `J'Wr` too.
    fn place(
        &self,
        gf: &mut [Vec<f64>],
        bf: &mut [Vec<f64>],
        n: usize,
        (p, r0): (usize, usize),
        (q, c0): (usize, usize),
    ) {
        let (rows, width) = (self.range(p).len(), self.range(q).len());
        let (gb, bb) = self.block(p, q);
        for ((g, b), (gk, bk)) in gf.iter_mut().zip(bf.iter_mut()).zip(gb.iter().zip(bb)) {
            for i in 0..rows {
                let j0 = if p == q { i } else { 0 };
                for (j, v) in gk[i * width..(i + 1) * width].iter().enumerate().skip(j0) {
                    g[(r0 + i) * n + c0 + j] = *v;
                    g[(c0 + j) * n + r0 + i] = *v;
                }
            }
            if p == q {
                b[r0..r0 + rows].copy_from_slice(bk);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three maps of 3, 1 and 2 columns on two channels, with responses that are exactly
    /// 0 on some samples (a node not yet read): every set, in every order, reads the bits
    /// `normal` sums for it — so the forward selection chooses as it did.
    #[test]
    fn a_set_read_from_the_products_has_the_bits_summed_for_it() {
        let len = 50;
        let v = |k: usize, c: usize, t: usize| {
            let x = ((k * 7 + c * 3 + t) as f64 * 0.37).sin() * (1.0 + k as f64);
            if (t + k).is_multiple_of(5) {
                0.0
            } else {
                x / 3.0
            }
        };
        let col =
            |k: usize| -> Vec<Vec<f64>> { (0..2).map(|c| (0..len).map(|t| v(k, c, t)).collect()).collect() };
        let maps: Vec<Vec<Vec<Vec<f64>>>> =
            vec![vec![col(0), col(1), col(2)], vec![col(3)], vec![col(4), col(5)]];
        let r: Vec<Vec<f64>> =
            (0..2).map(|c| (0..len).map(|t| ((c + t) as f64 * 0.11).cos() / 7.0).collect()).collect();
        let w: Vec<Vec<f64>> =
            (0..2).map(|c| (0..len).map(|t| 0.5 + ((t * (c + 1)) % 3) as f64 / 3.0).collect()).collect();
        let folds: Vec<usize> = (0..len).map(|t| (t / 4) % 3).collect();
        let s = Samples { r: &r, w: &w, folds: &folds };
        let products = Products::new(&maps, s, 3);
        for set in [vec![0], vec![2], vec![0, 2], vec![2, 0], vec![1, 2, 0], vec![2, 1, 0], vec![0, 1, 2]] {
            let cols: Vec<&Vec<Vec<f64>>> = set.iter().flat_map(|&m| maps[m].iter()).collect();
            let (read, summed) = (products.normal(&set), normal(&cols, s, 3));
            let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
            assert_eq!(read.n, summed.n);
            assert_eq!(bits(&read.g), bits(&summed.g), "{set:?}");
            assert_eq!(bits(&read.b), bits(&summed.b), "{set:?}");
            for f in 0..3 {
                assert_eq!(bits(&read.gf[f]), bits(&summed.gf[f]), "{set:?} fold {f}");
                assert_eq!(bits(&read.bf[f]), bits(&summed.bf[f]), "{set:?} fold {f}");
            }
        }
        // Taken the other way round, a product has other bits somewhere: the order is
        // what the blocks must keep.
        let (ab, ba) = (products.normal(&[0, 2]), products.normal(&[2, 0]));
        let differs =
            (0..3).any(|i| (0..2).any(|j| ab.g[i * 5 + 3 + j].to_bits() != ba.g[(2 + i) * 5 + j].to_bits()));
        assert!(differs, "a pair's products taken in both orders were equal to the bit");
    }
}
