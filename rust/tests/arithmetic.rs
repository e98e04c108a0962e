//! Deterministic mode through the public API (docs/conventions.md, "Arithmetic"): the switch,
//! that it keeps the loops (fused where the CPU has FMA) and changes only the products that
//! would go to faer (run-time sizes above 12), by rounding. (That the fused loops give the
//! same bits with every instruction set is tested from Python, which can force the other
//! loops: tests/linear/test_arithmetic.py.) One test, as the switch is process-wide and the
//! tests of one binary run in parallel.

mod common;

use common::{random_model, Rng};
use kfast::{deterministic, filter, instruction_set, set_deterministic, FilterResult, Series, UpdateForm};

#[test]
fn deterministic_mode_keeps_the_loops_and_changes_only_faers_products() {
    let mut rng = Rng::new(11);
    let steps = 200;
    let mut cases = Vec::new();
    for (n, m) in [(4, 2), (20, 3)] {
        let model = random_model(&mut rng, n, m, 0, false, None).unwrap();
        cases.push((model, rng.normals(steps, m), n, m));
    }
    let run_all = || -> Vec<FilterResult> {
        cases
            .iter()
            .map(|(model, y, n, m)| {
                let (x0, p0) = (vec![0.0; *n], common::eye(*n));
                filter(model, Series::new("y", y, steps, *m).unwrap(), None, &x0, &p0, UpdateForm::Joseph).unwrap()
            })
            .collect()
    };

    let was = set_deterministic(false);
    let default = run_all();
    let default_set = instruction_set();
    assert!(!set_deterministic(true));
    assert!(deterministic());
    let exact = run_all();
    let exact_set = instruction_set();
    assert_eq!(run_all()[1].p_filt, exact[1].p_filt, "deterministic runs repeat bit for bit");
    set_deterministic(was);

    if default_set.ends_with("+fma") {
        // The same loops; n = 4 never reaches faer.
        assert_eq!(exact_set, default_set);
        assert_eq!(exact[0].p_filt, default[0].p_filt);
        assert_ne!(exact[1].p_filt, default[1].p_filt, "n = 20 runs its products in faer by default");
    }
    for (d, e) in default.iter().zip(&exact) {
        for (a, b) in d.p_filt.iter().zip(&e.p_filt) {
            assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "{a} against {b}");
        }
        assert!((d.loglik - e.loglik).abs() <= 1e-10 * e.loglik.abs());
    }
}
