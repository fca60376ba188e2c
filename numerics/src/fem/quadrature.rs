//! Symmetric quadrature rules on the reference tetrahedron, in barycentric coordinates.
//! Weights sum to 1/6, the reference volume.

/// A point (barycentric coordinates L0..L3) and its weight.
pub type Point = ([f64; 4], f64);

/// Exact for polynomials of degree 1 (one point, the centroid).
pub fn degree1() -> Vec<Point> {
    vec![([0.25; 4], 1.0 / 6.0)]
}

/// Exact for degree 2 (4 points).
pub fn degree2() -> Vec<Point> {
    let a = 0.138_196_601_125_010_5;
    let b = 1.0 - 3.0 * a;
    orbit4(a, b, 1.0 / 24.0)
}

/// Exact for degree 5 (14 points, all weights positive).
pub fn degree5() -> Vec<Point> {
    let mut pts = orbit4(
        0.092_735_250_310_891_23,
        1.0 - 3.0 * 0.092_735_250_310_891_23,
        0.012_248_840_519_393_66,
    );
    pts.extend(orbit4(
        0.310_885_919_263_300_6,
        1.0 - 3.0 * 0.310_885_919_263_300_6,
        0.018_781_320_953_002_64,
    ));
    let (c, d) = (0.454_496_295_874_350_4, 0.045_503_704_125_649_6);
    let w = 0.007_091_003_462_846_911;
    for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
        let mut l = [d; 4];
        l[i] = c;
        l[j] = c;
        pts.push((l, w));
    }
    pts
}

/// The 4 points with one barycentric coordinate `b` and the others `a`.
fn orbit4(a: f64, b: f64, w: f64) -> Vec<Point> {
    (0..4)
        .map(|k| {
            let mut l = [a; 4];
            l[k] = b;
            (l, w)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn factorial(n: u32) -> f64 {
        (1..=n).map(f64::from).product()
    }

    /// ∫ x^a y^b z^c over the unit tet = a! b! c! / (a+b+c+3)!.
    fn check(rule: &[Point], degree: u32) {
        for a in 0..=degree {
            for b in 0..=degree - a {
                for c in 0..=degree - a - b {
                    let exact = factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3);
                    let q: f64 = rule
                        .iter()
                        .map(|(l, w)| w * l[1].powi(a as i32) * l[2].powi(b as i32) * l[3].powi(c as i32))
                        .sum();
                    assert!(
                        (q - exact).abs() < 1e-15 + 1e-13 * exact,
                        "x^{a} y^{b} z^{c}: {q} vs {exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn rules_integrate_monomials_exactly_up_to_their_degree() {
        check(&degree1(), 1);
        check(&degree2(), 2);
        check(&degree5(), 5);
    }

    #[test]
    fn degree2_rule_is_not_exact_for_degree3() {
        // Guards the test above: it must be able to fail.
        let rule = degree2();
        let q: f64 = rule.iter().map(|(l, w)| w * l[1].powi(3)).sum();
        assert!((q - 6.0 / factorial(6)).abs() > 1e-6);
    }
}
