//! Times one sparse Cholesky solve with 1, 8 and 32 right-hand sides on matrices exported by
//! `ves matrices`, factorised with faer's AMD ordering (usage: cargo run --release --example
//! solve_bench KM.h5).

use faer::sparse::SymbolicSparseColMat;
use std::time::Instant;
use ves_pipeline::linsolve::Cholesky;

fn main() -> anyhow::Result<()> {
    let path = std::env::args()
        .nth(1)
        .ok_or_else(|| anyhow::anyhow!("usage: solve_bench KM.h5"))?;
    let f = ves_format::file::open(std::path::Path::new(&path))?;
    let cp: Vec<u64> = f.dataset("col_ptr")?.read_raw()?;
    let ri: Vec<u64> = f.dataset("row_idx")?.read_raw()?;
    let k: Vec<f64> = f.dataset("k")?.read_raw()?;
    let n = cp.len() - 1;
    let pattern = SymbolicSparseColMat::new_checked(
        n,
        n,
        cp.iter().map(|&x| x as usize).collect(),
        None,
        ri.iter().map(|&x| x as usize).collect(),
    );
    let t = Instant::now();
    let sym = faer::sparse::linalg::cholesky::factorize_symbolic_cholesky(
        pattern.as_ref(),
        faer::Side::Lower,
        faer::sparse::linalg::cholesky::SymmetricOrdering::Amd,
        Default::default(),
    )
    .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut chol = Cholesky::factor(sym, &pattern, &k, 0.0)?;
    println!(
        "factor {:.3} s, {} values",
        t.elapsed().as_secs_f64(),
        chol.factor_len()
    );
    for nrhs in [1usize, 4, 8, 16, 32] {
        let mut x = vec![1.0; n * nrhs];
        let t = Instant::now();
        let reps = 5;
        for _ in 0..reps {
            chol.solve_many_in_place(&mut x, nrhs);
        }
        let s = t.elapsed().as_secs_f64() / reps as f64;
        println!(
            "nrhs {nrhs}: {:.1} ms per block, {:.2} ms per vector",
            1e3 * s,
            1e3 * s / nrhs as f64
        );
    }
    chol.set_parallelism(faer::Par::rayon(2));
    for nrhs in [1usize, 8] {
        let mut x = vec![1.0; n * nrhs];
        let t = Instant::now();
        for _ in 0..5 {
            chol.solve_many_in_place(&mut x, nrhs);
        }
        println!(
            "2 threads, nrhs {nrhs}: {:.1} ms per block",
            1e3 * t.elapsed().as_secs_f64() / 5.0
        );
    }
    Ok(())
}
