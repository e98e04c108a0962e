//! Deterministic mode through the public API (docs/conventions.md, "Arithmetic"): the switch
//! and the instruction set it selects, and that fused and unfused filters agree to rounding.
//! (That deterministic results are the same bits with every instruction set is tested from
//! Python, which can force the baseline loops: tests/linear/test_arithmetic.py.) One test, as
//! the switch is process-wide and the tests of one binary run in parallel.

mod common;

use common::{random_model, Rng};
use kfast::{deterministic, filter, instruction_set, set_deterministic, Series, UpdateForm};

#[test]
fn deterministic_mode_never_fuses_and_agrees_with_the_default_to_rounding() {
    let mut rng = Rng::new(11);
    let (n, m, steps) = (4, 2, 200);
    let model = random_model(&mut rng, n, m, 0, false, None).unwrap();
    let y = rng.normals(steps, m);
    let (x0, p0) = (vec![0.0; n], common::eye(n));
    let run = || filter(&model, Series::new("y", &y, steps, m).unwrap(), None, &x0, &p0, UpdateForm::Joseph).unwrap();

    let was = set_deterministic(false);
    let fused = run();
    let default_set = instruction_set();
    assert!(!set_deterministic(true));
    assert!(deterministic());
    assert_ne!(instruction_set(), "avx2+fma");
    let plain = run();
    assert_eq!(run().x_filt, plain.x_filt, "deterministic runs repeat bit for bit");
    set_deterministic(was);

    if default_set == "avx2+fma" {
        assert_ne!(fused.p_filt, plain.p_filt, "the default loops on this CPU fuse");
    }
    for (f, p) in fused.p_filt.iter().zip(&plain.p_filt) {
        assert!((f - p).abs() <= 1e-12 * p.abs().max(1.0), "{f} against {p}");
    }
    assert!((fused.loglik - plain.loglik).abs() <= 1e-10 * plain.loglik.abs());
}
