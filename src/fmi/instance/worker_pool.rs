//! The worker pool: the instance's own rayon threads, started off the caller's thread by a
//! [`ThreadRunner`] and joined when the instance is dropped.
use super::status::panic_message;
#[cfg(feature = "parallel")]
use std::sync::Arc;

/// A job for a [`ThreadRunner`].
pub(crate) type Job<'a> = Box<dyn FnOnce() + Send + 'a>;

/// Runs a job on a short-lived thread of its own and waits for it to end; an error if the
/// thread cannot start or the job panics. A pool's threads are spawned from such a thread,
/// never from the caller's: spawning registers a TLS destructor on the spawning thread, and a
/// dlopen'ed library that a long-lived host thread holds one of is never unloaded. The C layer
/// (`fmi2Instantiate`) passes one built on `pthread_create` (`ffi::run_on_os_thread`, which
/// tells why in full); Rust callers get [`scoped_thread`].
pub(crate) type ThreadRunner = fn(Job<'_>) -> Result<(), String>;

/// The default [`ThreadRunner`]: a scoped std thread. Starting it registers the TLS destructor
/// on the calling thread, which only matters to a library that is unloaded: not to Rust
/// callers, which link the crate in.
pub(crate) fn scoped_thread(job: Job<'_>) -> Result<(), String> {
    std::thread::scope(|s| s.spawn(job).join())
        .map_err(|p| format!("internal error (panic): {}", panic_message(&*p)))
}

/// A rayon pool whose threads are std threads this instance owns and joins when dropped, so
/// that none outlives `fmi2FreeInstance` (hosts unload the library right after).
#[cfg(feature = "parallel")]
pub struct WorkerPool {
    pool: Option<rayon::ThreadPool>,
    handles: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>>,
}

#[cfg(feature = "parallel")]
impl WorkerPool {
    /// Threads: `MPS_FMI_THREADS` if set, else the available parallelism, spawned from a
    /// scoped thread (`scoped_thread`; the C layer's instances use `with_runner`).
    pub fn new(name: &str) -> Result<Self, String> {
        Self::with_runner(name, scoped_thread)
    }

    /// The threads are spawned from a short-lived thread that `run` starts, never from the
    /// caller's thread (see [`ThreadRunner`]).
    pub(crate) fn with_runner(name: &str, run: ThreadRunner) -> Result<Self, String> {
        let mut pool = None;
        run(Box::new(|| pool = Some(Self::spawn(name))))?;
        pool.unwrap_or_else(|| Err("internal error: the thread did not run".into()))
    }

    fn spawn(name: &str) -> Result<Self, String> {
        let n = std::env::var("MPS_FMI_THREADS")
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
            .filter(|&n| n > 0)
            .unwrap_or_else(|| {
                std::thread::available_parallelism()
                    .map(|n| n.get())
                    .unwrap_or(1)
            });
        let handles: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>> = Arc::default();
        let h = handles.clone();
        let prefix: String = format!("fmu-{}", name.chars().take(8).collect::<String>());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .spawn_handler(move |thread| {
                let idx = thread.index();
                let handle = std::thread::Builder::new()
                    .name(format!("{prefix}-{idx}"))
                    .spawn(move || thread.run())?;
                h.lock().unwrap_or_else(|e| e.into_inner()).push(handle);
                Ok(())
            })
            .build()
            .map_err(|e| format!("cannot start worker threads: {e}"))?;
        Ok(WorkerPool {
            pool: Some(pool),
            handles,
        })
    }
    /// Runs f on the pool (rayon work inside f uses this pool's threads).
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(p) => p.install(f),
            None => f(),
        }
    }
}

#[cfg(feature = "parallel")]
impl Drop for WorkerPool {
    fn drop(&mut self) {
        drop(self.pool.take());
        let handles: Vec<_> = self
            .handles
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .drain(..)
            .collect();
        for h in handles {
            let _ = h.join();
        }
    }
}

/// Without the `parallel` feature there are no worker threads.
#[cfg(not(feature = "parallel"))]
pub struct WorkerPool;

#[cfg(not(feature = "parallel"))]
impl WorkerPool {
    pub fn new(_name: &str) -> Result<Self, String> {
        Ok(WorkerPool)
    }
    pub(crate) fn with_runner(_name: &str, _run: ThreadRunner) -> Result<Self, String> {
        Ok(WorkerPool)
    }
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        f()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scoped_thread_runs_the_job_on_another_thread() {
        let me = std::thread::current().id();
        let mut elsewhere = false;
        scoped_thread(Box::new(|| elsewhere = std::thread::current().id() != me)).unwrap();
        assert!(elsewhere);
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let e = scoped_thread(Box::new(|| panic!("boom")));
        std::panic::set_hook(prev);
        assert!(e.unwrap_err().contains("boom"));
    }
}
