//! Listing plugins from worker processes: opening a library runs its initialisers, which may
//! end, crash or hang the process, so `tribo laws` and Python's `laws()` open them in a worker
//! and leave out, one at a time, each file whose loading took a worker down.

use std::path::PathBuf;

use crate::terms::WorkerFailure;

/// The most plugin files a listing leaves out before it gives up (each costs a worker process).
pub const MAX_SKIPPED: usize = 256;

/// A plugin file a listing left out, and why (loading it ended, crashed or hung a worker).
pub type Skipped = (PathBuf, String);

/// Run `attempt` (one listing in a fresh worker, leaving out the files it is given) until it
/// answers: a worker that failed while loading a library (`library `FILE` (while loading it)`
/// in its failure) has that file added to the ones left out, with the failure as the reason,
/// and the listing runs again. Any other failure, or more than [`MAX_SKIPPED`] files, is the
/// error. The listing and the files left out.
pub fn skipping_unloadable<T>(
    mut attempt: impl FnMut(&[Skipped]) -> Result<T, WorkerFailure>,
) -> Result<(T, Vec<Skipped>), WorkerFailure> {
    let mut skip: Vec<Skipped> = Vec::new();
    loop {
        match attempt(&skip) {
            Ok(t) => return Ok((t, skip)),
            Err(e @ (WorkerFailure::Study(_) | WorkerFailure::Interrupted)) => return Err(e),
            Err(e) => {
                let text = e.to_string();
                match tribo_plugin_api::loader::loading_library(&text) {
                    Some(path)
                        if !skip.iter().any(|(p, _)| *p == path) && skip.len() < MAX_SKIPPED =>
                    {
                        skip.push((
                            path,
                            format!("loading it in a worker process failed: {text}"),
                        ));
                    }
                    _ => return Err(e),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_library_that_took_a_worker_down_is_left_out_once_then_the_listing_answers() {
        let fail = |file: &str| WorkerFailure::NoReply {
            code: 0,
            running: vec![format!("library `{file}` (while loading it)")],
            last_words: None,
        };
        let mut calls = 0;
        let (answer, skipped) = skipping_unloadable(|skip| {
            calls += 1;
            match skip.len() {
                0 => Err(fail("/p/a.so")),
                1 => Err(fail("/p/b.so")),
                _ => Ok("listed"),
            }
        })
        .expect("answers");
        assert_eq!((answer, calls), ("listed", 3));
        let files: Vec<_> = skipped
            .iter()
            .map(|(p, _)| p.display().to_string())
            .collect();
        assert_eq!(files, ["/p/a.so", "/p/b.so"]);
        assert!(skipped[0].1.contains("status 0"), "{}", skipped[0].1);
        // The same file failing again is not skipped twice: the failure is the error.
        let again = skipping_unloadable::<()>(|_| Err(fail("/p/a.so")));
        assert!(matches!(again, Err(WorkerFailure::NoReply { .. })));
        // A failure that is not a library's loading is the error at once.
        let other = skipping_unloadable::<()>(|_| Err(WorkerFailure::Study("bad".into())));
        assert!(matches!(other, Err(WorkerFailure::Study(_))));
    }
}
