//! A symmetric matrix in single precision with each pair of entries stored once, laid out for
//! its product with a vector: the nonlinear step's quartic coefficients H (P × P, P = r(r+1)/2).
//! Read once a product instead of twice, H at r = 30 is 453 KB instead of 865 KB — within the
//! core's second-level cache (512 KB here) — and each value loaded feeds two products, where a
//! row-by-row product fed one.
//!
//! Layout: the matrix padded with zeros to n₈ = 8⌈n/8⌉ is cut into panels of eight columns;
//! panel J holds the blocks (I, J), I = 0..=J, above and on the diagonal. Each panel is stored
//! as two halves of four columns, and each half block by block (I ascending), each block column
//! by column (eight rows of a column contiguous). A block above the diagonal adds H_IJ s_J to
//! y_I and H_IJᵀ s_I to y_J; the diagonal block, itself symmetric, adds only the second.

/// Rows (and columns) of a block: one 8-lane single-precision register.
pub const BLOCK: usize = 8;

/// A symmetric n × n single-precision matrix stored by panels (module documentation).
#[derive(Clone, Debug, Default)]
pub struct Panels {
    n: usize,
    blocks: usize,
    data: Vec<f32>,
}

impl Panels {
    /// The panels of the symmetric n × n row-major matrix `h` (its upper triangle is read).
    /// Panics if `h` holds fewer than n² values.
    pub fn of_rows(h: &[f32], n: usize) -> Panels {
        assert!(
            h.len() >= n * n,
            "a {n} x {n} matrix needs {} values, not {}",
            n * n,
            h.len()
        );
        let blocks = n.div_ceil(BLOCK);
        let at = |i: usize, j: usize| if i < n && j < n { h[i * n + j] } else { 0.0 };
        let mut data = Vec::with_capacity(Self::len(blocks));
        for jb in 0..blocks {
            for half in 0..2 {
                for ib in 0..=jb {
                    for c in 0..BLOCK / 2 {
                        let j = BLOCK * jb + BLOCK / 2 * half + c;
                        data.extend((0..BLOCK).map(|k| at(BLOCK * ib + k, j)));
                    }
                }
            }
        }
        Panels { n, blocks, data }
    }

    /// Values stored for `blocks` panels: each block of 64 once.
    fn len(blocks: usize) -> usize {
        blocks * (blocks + 1) / 2 * BLOCK * BLOCK
    }

    /// Order n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The padded order n₈ = 8⌈n/8⌉: the length the vectors of [`Panels::times`] must have.
    pub fn padded(&self) -> usize {
        self.blocks * BLOCK
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        4 * self.data.len()
    }

    /// y = H s. `s` (at least [`Panels::padded`] long, zero beyond n), `y` and the work space
    /// `w` as long. The eight products of a panel's row are summed in single precision, then
    /// added in double: the rounding of a row-by-row product's eight-lane sums (a relative
    /// 1e-7 at n = 465, where summing in single throughout gave 5e-7).
    pub fn times(&self, s: &[f32], y: &mut [f64], w: &mut [f32]) {
        let m = self.padded();
        assert!(
            s.len() >= m && y.len() >= m && w.len() >= m,
            "vectors of {m} values needed"
        );
        if !crate::os::panels_times_simd(&self.data, self.blocks, s, y, w) {
            self.times_portable(s, y, w);
        }
    }

    /// [`Panels::times`] one value at a time, the same sums in the same order (a processor
    /// without AVX2 and FMA).
    fn times_portable(&self, s: &[f32], y: &mut [f64], w: &mut [f32]) {
        y[..self.padded()].fill(0.0);
        let mut at = 0;
        for jb in 0..self.blocks {
            for half in 0..2 {
                let j0 = BLOCK * jb + BLOCK / 2 * half;
                let mut t = [0.0f32; BLOCK / 2];
                for ib in 0..=jb {
                    for k in 0..BLOCK {
                        let i = BLOCK * ib + k;
                        let mut yi = if half == 0 { 0.0 } else { w[i] };
                        for (c, tc) in t.iter_mut().enumerate() {
                            let h = self.data[at + c * BLOCK + k];
                            yi += h * s[j0 + c];
                            *tc += h * s[i];
                        }
                        // Above the diagonal only (the diagonal block's products are its t).
                        match (ib < jb, half) {
                            (false, _) => {}
                            (true, 0) => w[i] = yi,
                            (true, _) => y[i] += f64::from(yi),
                        }
                    }
                    at += BLOCK * BLOCK / 2;
                }
                for (c, tc) in t.iter().enumerate() {
                    y[j0 + c] += f64::from(*tc);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric n × n matrix of values of mixed sign and size, and a vector.
    fn case(n: usize) -> (Vec<f32>, Vec<f32>) {
        let v = |a: usize, b: usize| ((a.min(b) * 31 + a.max(b) * 17) % 97) as f32 * 1e-2 - 0.4;
        let h = (0..n * n).map(|i| v(i / n, i % n) + if i % (n + 1) == 0 { 3.0 } else { 0.0 });
        let s = (0..n).map(|i| ((i * 13) % 11) as f32 * 0.1 - 0.5);
        (h.collect(), s.collect())
    }

    /// The product (vector kernel and one value at a time) equals the row-by-row one in double
    /// precision to single-precision rounding at sizes on, below and above a block boundary
    /// (padding), and holds each pair once.
    #[test]
    fn the_product_is_the_full_matrix_product() {
        for n in [1, 7, 8, 9, 21, 64, 210] {
            let (h, s) = case(n);
            let p = Panels::of_rows(&h, n);
            let m = p.padded();
            assert!(
                p.bytes() <= 4 * (n + 8) * (n + 8) / 2 + 4 * 64 * m / 8,
                "n {n}: {} bytes",
                p.bytes()
            );
            let mut sp = s.clone();
            sp.resize(m, 0.0);
            let (mut y, mut w) = (vec![f64::NAN; m], vec![f32::NAN; m]);
            let mut portable = vec![f64::NAN; m];
            p.times(&sp, &mut y, &mut w);
            p.times_portable(&sp, &mut portable, &mut w);
            let mut scale = 0.0f64;
            let exact: Vec<f64> = (0..n)
                .map(|i| {
                    let row = (0..n).map(|j| f64::from(h[i * n + j]) * f64::from(s[j]));
                    let terms: Vec<f64> = row.collect();
                    scale = scale.max(terms.iter().map(|x| x.abs()).sum());
                    terms.iter().sum()
                })
                .collect();
            for i in 0..n {
                assert!(
                    (y[i] - exact[i]).abs() <= 1e-6 * scale,
                    "n {n}, row {i}: {} vs {}",
                    y[i],
                    exact[i]
                );
                let d = (portable[i] - exact[i]).abs();
                assert!(
                    d <= 1e-6 * scale,
                    "n {n}, row {i}: {} vs {} one at a time",
                    portable[i],
                    exact[i]
                );
            }
            for (i, yi) in y.iter().enumerate().skip(n) {
                assert_eq!(*yi, 0.0, "n {n}: padding row {i}");
            }
        }
    }
}
