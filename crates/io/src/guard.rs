//! A panic inside a dependency (the parquet decoder on a corrupt page) must not end the run with a backtrace:
//! every read of a file runs under [`guarded`], which turns a panic into one
//! [`IngestError::Panicked`] line naming the file (exit 3). While a guard is active the panic
//! hook stays silent (the message becomes the error's); outside it the default hook prints.
//!
//! An abort (an allocation failure) cannot be caught here: each guard also tells a supervising
//! process which files are being decoded ([`dbbcal_supervise::reading`]), so that the
//! supervisor can name them when the process dies.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Once;

use super::{one_line, IngestError};

/// Guards running now (several consumer threads decode at once: the hook cannot tell whose).
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

/// Runs `f`, the reading of `path`, announced to a supervising process while it runs; a panic
/// inside becomes [`IngestError::Panicked`].
pub(crate) fn guarded<T>(
    path: &Path,
    f: impl FnOnce() -> Result<T, IngestError>,
) -> Result<T, IngestError> {
    let _reading = dbbcal_supervise::reading([path]);
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

/// Decodes every column of every row of `path`, dropping the rows as they stream: the
/// supervisor's probe of one file after a scan of several crashed (`dbbcal_supervise::probe`).
/// Whether the process survives is the answer; the error is only for the caller's log.
pub fn decode_whole_file(path: &Path) -> Result<(), IngestError> {
    guarded(path, || {
        let file = crate::pq::ParquetFile::open(path)?;
        let columns: Vec<(usize, Option<arrow_schema::DataType>)> =
            (0..file.schema().fields().len())
                .map(|i| (i, None))
                .collect();
        for batch in file.reader(path, &columns, None)? {
            batch.map_err(|e| crate::pq::not_parquet(path, e))?;
        }
        Ok(())
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
