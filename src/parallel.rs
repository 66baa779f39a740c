//! Thread-pool policy: every parallel loop of octaray (frames, the photon pass, the BVH
//! build, image encoding) runs on rayon's pool through [`parallel`], and on the calling
//! thread where worker threads cannot start (a process or container limit), where rayon
//! itself would panic.

use std::sync::OnceLock;

/// Runs `f` on `threads` worker threads: rayon's current pool when it has that many
/// (the command line sizes the global pool by `--threads`) or none is asked for, else
/// a pool of its own. Should that pool fail to start (a process limit), `f` runs on
/// the current pool: the same result, other threads.
pub fn with_threads<R: Send>(threads: Option<usize>, f: impl FnOnce() -> R + Send) -> R {
    match threads {
        Some(n) if n != self::threads() => {
            match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
                Ok(pool) => pool.install(f),
                Err(_) => f(),
            }
        }
        _ => f(),
    }
}

/// Whether rayon's global pool runs: `Some` once [`start_pool`] or [`parallel`] has
/// tried to start it.
static POOL: OnceLock<bool> = OnceLock::new();

/// Starts rayon's global pool with `threads` workers (the command line's `--threads`),
/// before any parallel loop. One thread needs no worker: should it not start, the
/// parallel loops run on the calling thread.
pub fn start_pool(threads: usize) -> Result<(), rayon::ThreadPoolBuildError> {
    let started = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    let _ = POOL.set(started.is_ok());
    if threads == 1 { Ok(()) } else { started }
}

/// Whether a parallel loop may run on rayon's pools: on a worker of one, or when the
/// global pool runs, which is started here at the first such loop (where rayon would
/// start it). Where its threads cannot start (a process or container limit), rayon
/// would panic at every parallel loop: they run on the calling thread instead, and
/// [`serial`] tells.
pub fn parallel() -> bool {
    rayon::current_thread_index().is_some()
        || *POOL.get_or_init(|| rayon::ThreadPoolBuilder::new().build_global().is_ok())
}

/// Whether parallel loops have been running on the calling thread because the worker
/// threads could not start.
pub fn serial() -> bool {
    POOL.get() == Some(&false)
}

/// The threads parallel loops run on here: the current pool's, or 1 where its threads
/// could not start ([`parallel`]).
pub fn threads() -> usize {
    if parallel() {
        rayon::current_num_threads()
    } else {
        1
    }
}
