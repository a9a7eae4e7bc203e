//! The worker pool: the instance's own rayon threads, started off the caller's thread and
//! joined when the instance is dropped.
#[cfg(feature = "parallel")]
use std::sync::Arc;

/// A rayon pool whose threads are std threads this instance owns and joins when dropped, so
/// that none outlives `fmi2FreeInstance` (hosts unload the library right after).
#[cfg(feature = "parallel")]
pub struct WorkerPool {
    pool: Option<rayon::ThreadPool>,
    handles: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>>,
}

#[cfg(feature = "parallel")]
impl WorkerPool {
    /// Threads: `MPS_FMI_THREADS` if set, else the available parallelism. The threads are
    /// spawned from a short-lived thread of the library's own, never from the host's thread:
    /// spawning registers a TLS destructor on the spawning thread that would keep the library
    /// from unloading (see [`crate::fmi::ffi::run_on_os_thread`]).
    pub fn new(name: &str) -> Result<Self, String> {
        crate::fmi::ffi::run_on_os_thread(|| Self::spawn(name))?
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
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        f()
    }
}
