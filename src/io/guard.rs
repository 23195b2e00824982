//! A panic inside a dependency (polars on a corrupt page) must not end the run with a backtrace:
//! every read of a file runs under [`guarded`], which turns a panic into one
//! [`IngestError::Panicked`] line naming the file (exit 3). While a guard is active the panic
//! hook stays silent (the message becomes the error's); outside it the default hook prints.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Once;

use super::{one_line, IngestError};

/// Guards running now (polars may panic on one of its own threads: the hook cannot tell whose).
static ACTIVE: AtomicUsize = AtomicUsize::new(0);
static HOOK: Once = Once::new();

fn install_quiet_hook() {
    HOOK.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if ACTIVE.load(Ordering::SeqCst) == 0 {
                default(info);
            }
        }));
    });
}

/// Runs `f`, the reading of `path`; a panic inside becomes [`IngestError::Panicked`].
pub(crate) fn guarded<T>(
    path: &Path,
    f: impl FnOnce() -> Result<T, IngestError>,
) -> Result<T, IngestError> {
    install_quiet_hook();
    ACTIVE.fetch_add(1, Ordering::SeqCst);
    let result = catch_unwind(AssertUnwindSafe(f));
    ACTIVE.fetch_sub(1, Ordering::SeqCst);
    result.unwrap_or_else(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        Err(IngestError::Panicked {
            path: path.to_path_buf(),
            message: one_line(message),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_while_reading_becomes_one_line_naming_the_file() {
        let r: Result<(), _> = guarded(Path::new("enc/day1.parquet"), || {
            panic!("index out of bounds: the len is 3\nbut the index is 7")
        });
        let e = r.unwrap_err().to_string();
        assert!(e.starts_with("enc/day1.parquet: "), "{e}");
        assert!(
            e.contains("index out of bounds") && !e.contains('\n'),
            "{e}"
        );
        assert_eq!(guarded(Path::new("x"), || Ok(3)).unwrap(), 3);
    }
}
