//! Sizes of allocations that follow from user input (steps, lags, series, matrix sizes),
//! checked before anything is allocated: an impossible request becomes an error naming the
//! argument, never an abort ("capacity overflow", out of memory) nor a machine swapped to a
//! halt by a typo such as `steps=10**10`.

use crate::error::{Error, Result};

/// `Ok` when `f64` arrays of the given shapes fit in memory together: their element count
/// does not overflow and their bytes do not exceed the machine's physical memory. `arg` is
/// the argument the sizes come from.
pub(crate) fn check_f64_arrays(arg: &'static str, shapes: &[&[usize]]) -> Result<()> {
    let bytes = shapes
        .iter()
        .try_fold(0usize, |total, shape| {
            let elements = shape.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d))?;
            total.checked_add(elements.checked_mul(size_of::<f64>())?)
        })
        .ok_or_else(|| Error::arg(arg, "is too large: the arrays it asks for would not fit in memory"))?;
    match physical_memory() {
        Some(limit) if bytes > limit => Err(Error::arg(
            arg,
            format!(
                "is too large: the arrays it asks for need {}, more than this machine's memory ({})",
                human_bytes(bytes),
                human_bytes(limit)
            ),
        )),
        _ => Ok(()),
    }
}

/// The machine's physical memory in bytes, where the platform tells.
fn physical_memory() -> Option<usize> {
    #[cfg(unix)]
    {
        // SAFETY: sysconf only reads system configuration; a negative result means unknown.
        let (pages, page_size) = unsafe { (libc::sysconf(libc::_SC_PHYS_PAGES), libc::sysconf(libc::_SC_PAGESIZE)) };
        if pages > 0 && page_size > 0 {
            return (pages as usize).checked_mul(page_size as usize);
        }
    }
    None
}

/// `1.5 TiB`-style sizes for messages.
fn human_bytes(bytes: usize) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    format!("{value:.1} {}", UNITS[unit])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_arrays_fit() {
        assert!(check_f64_arrays("steps", &[&[1000, 4], &[1000, 4, 4]]).is_ok());
        assert!(check_f64_arrays("steps", &[&[0, usize::MAX]]).is_ok());
    }

    #[test]
    fn overflowing_or_huge_sizes_name_the_argument() {
        for shapes in [&[&[usize::MAX, 2][..]][..], &[&[1 << 40, 1 << 30]], &[&[usize::MAX / 8 + 1]]] {
            let err = check_f64_arrays("steps", shapes).unwrap_err().to_string();
            assert!(err.starts_with("steps: is too large"), "{err}");
        }
    }

    #[test]
    fn sizes_are_printed_in_binary_units() {
        assert_eq!(human_bytes(512), "512.0 B");
        assert_eq!(human_bytes(3 << 30), "3.0 GiB");
    }
}
