//! The memory limit: every dense voxel array (a TIFF being decoded, a grid to voxelise or generate,
//! the work arrays of `measure`) is sized from its declared shape and checked against one limit
//! *before* anything is allocated, so that a typo (`--voxel-size 1nm`) or a crafted file (600 TIFF
//! pages sharing one strip) is a clear error instead of an abort or an OOM kill.
//!
//! The limit is [`DEFAULT_MEMORY_LIMIT`] (16 GiB), lowered to ¾ of the machine's physical memory
//! where that is known (Linux `/proc/meminfo`) and smaller: beyond physical memory a run is killed
//! or swaps for hours, and ¾ leaves room for the system and the program's other buffers; 16 GiB
//! (a 2048 × 2048 × 1024 `u32` volume, far larger than any segmentation we know of) keeps a typo
//! from taking a shared cluster node. The environment variable [`MEMORY_LIMIT_ENV`]
//! (`TISSUEFIT_MEMORY_LIMIT=64GiB`, `500MB`, or plain bytes) replaces it.

use super::ImagingError;

/// Environment variable that sets the memory limit (e.g. `64GiB`, `500MB`, `1000000`).
pub const MEMORY_LIMIT_ENV: &str = "TISSUEFIT_MEMORY_LIMIT";

/// Memory limit without [`MEMORY_LIMIT_ENV`], on a machine with at least 21⅓ GiB of memory: 16 GiB.
pub const DEFAULT_MEMORY_LIMIT: u64 = 16 << 30;

/// The memory limit in bytes: [`MEMORY_LIMIT_ENV`] when set, else [`DEFAULT_MEMORY_LIMIT`] or ¾ of
/// the physical memory, whichever is smaller. An unreadable variable is an error naming it.
pub fn memory_limit() -> Result<u64, ImagingError> {
    match std::env::var(MEMORY_LIMIT_ENV) {
        Ok(text) => parse_bytes(&text).ok_or_else(|| {
            ImagingError::Limit(format!(
                "{MEMORY_LIMIT_ENV}={text:?} is not a size; give bytes with an optional unit, e.g. 64GiB or 500MB"
            ))
        }),
        Err(std::env::VarError::NotPresent) => {
            Ok(physical_memory().map_or(DEFAULT_MEMORY_LIMIT, |ram| DEFAULT_MEMORY_LIMIT.min(ram / 4 * 3)))
        }
        Err(std::env::VarError::NotUnicode(_)) => {
            Err(ImagingError::Limit(format!("{MEMORY_LIMIT_ENV} is not valid UTF-8; give e.g. 64GiB")))
        }
    }
}

/// Checks that `voxels` voxels of `bytes_per_voxel` bytes each fit the memory limit. `what` names
/// the array and where its size came from (the file, the option), `fix` what the user can change;
/// both go into the message, with the numbers and how to raise the limit. `None` voxels means the
/// count overflowed.
pub fn check_voxel_memory(
    voxels: Option<u64>,
    bytes_per_voxel: u64,
    what: &str,
    fix: &str,
) -> Result<(), ImagingError> {
    let limit = memory_limit()?;
    let needed = voxels.and_then(|v| v.checked_mul(bytes_per_voxel));
    if needed.is_some_and(|n| n <= limit) {
        return Ok(());
    }
    let needed = match needed {
        Some(n) => format!("{} ({bytes_per_voxel} bytes per voxel)", format_bytes(n)),
        None => "more bytes than a 64-bit count holds".to_string(),
    };
    Err(ImagingError::Limit(format!(
        "{what} needs {needed}, more than the memory limit of {}; {fix}, or raise the limit with {MEMORY_LIMIT_ENV} \
         (e.g. {MEMORY_LIMIT_ENV}=64GiB) if the machine has the memory",
        format_bytes(limit)
    )))
}

/// Bytes as `12.3 GiB` (binary units), with the exact count for small numbers.
pub fn format_bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["KiB", "MiB", "GiB", "TiB", "PiB"];
    if n < 1024 {
        return format!("{n} bytes");
    }
    let mut value = n as f64 / 1024.0;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    format!("{value:.1} {}", UNITS[unit])
}

/// `64GiB`, `64 GB`, `1.5G`, `500MB`, `1e9`, `1000000` → bytes. Single-letter and `iB` units are
/// binary (G = GiB), `B`-suffixed decimal ones are decimal (GB = 10⁹). `None` when unreadable,
/// negative or zero.
pub fn parse_bytes(text: &str) -> Option<u64> {
    let t = text.trim();
    let split = t.find(|c: char| c.is_ascii_alphabetic() && c != 'e' && c != 'E').unwrap_or(t.len());
    let (number, unit) = (t[..split].trim(), t[split..].trim());
    let value: f64 = number.parse().ok()?;
    let scale: f64 = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" => 1024.0,
        "m" | "mib" => 1024f64.powi(2),
        "g" | "gib" => 1024f64.powi(3),
        "t" | "tib" => 1024f64.powi(4),
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "tb" => 1e12,
        _ => return None,
    };
    let bytes = value * scale;
    (bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64).then_some(bytes as u64)
}

/// Total physical memory (bytes) from `/proc/meminfo`; `None` elsewhere or when unreadable.
fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.trim_start_matches("MemTotal:").trim().trim_end_matches("kB").trim().parse().ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_and_decimal_units() {
        assert_eq!(parse_bytes("64GiB"), Some(64 << 30));
        assert_eq!(parse_bytes("64 G"), Some(64 << 30));
        assert_eq!(parse_bytes("500MB"), Some(500_000_000));
        assert_eq!(parse_bytes("1.5k"), Some(1536));
        assert_eq!(parse_bytes("1e9"), Some(1_000_000_000));
        assert_eq!(parse_bytes("123"), Some(123));
        for bad in ["", "lots", "-1GiB", "0", "nan", "1e30GiB", "12 parsecs"] {
            assert_eq!(parse_bytes(bad), None, "{bad}");
        }
    }

    #[test]
    fn bytes_print_in_binary_units() {
        assert_eq!(format_bytes(100), "100 bytes");
        assert_eq!(format_bytes(16 << 30), "16.0 GiB");
        assert_eq!(format_bytes(3 << 19), "1.5 MiB");
    }

    #[test]
    fn the_default_limit_never_exceeds_16_gib_or_the_machine() {
        if std::env::var_os(MEMORY_LIMIT_ENV).is_some() {
            return;
        }
        let limit = memory_limit().unwrap();
        assert!(limit <= DEFAULT_MEMORY_LIMIT && limit > 0, "{limit}");
        if let Some(ram) = physical_memory() {
            assert!(limit <= ram, "{limit} > {ram}");
        }
        let err = check_voxel_memory(Some(1 << 40), 4, "a test grid", "make it smaller").unwrap_err().to_string();
        assert!(err.contains("a test grid needs 4.0 TiB") && err.contains(MEMORY_LIMIT_ENV), "{err}");
        assert!(check_voxel_memory(None, 4, "x", "y").is_err());
        assert!(check_voxel_memory(Some(1000), 4, "x", "y").is_ok());
    }
}
