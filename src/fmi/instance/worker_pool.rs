//! The worker pool: the threads an instance's solver work runs on. The C layer gives each
//! instance an executor of its own (`ffi::threads::InstanceThreads`: threads and allocations
//! owned by the instance, joined and freed when it is dropped, no library-global state); Rust
//! callers, which link the crate and never unload it, get a rayon pool of their own.
#[cfg(feature = "parallel")]
use super::status::panic_message;
use crate::physics::par::{self, BoxedExecutor};
#[cfg(feature = "parallel")]
use std::sync::Arc;

/// Threads an instance uses: `MPS_FMI_THREADS` if set (> 0), else the available parallelism.
pub fn instance_threads() -> usize {
    std::env::var("MPS_FMI_THREADS")
        .ok()
        .and_then(|s| s.parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or_else(|| {
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
        })
}

/// Where an instance's solver work runs.
pub struct WorkerPool(Kind);

enum Kind {
    /// An executor installed for the parallel loops (the C layer's instance threads).
    Executor(BoxedExecutor),
    /// A rayon pool whose threads are std threads this instance owns and joins when dropped.
    #[cfg(feature = "parallel")]
    Rayon {
        pool: Option<rayon::ThreadPool>,
        handles: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>>,
    },
    /// The calling thread alone.
    #[cfg(not(feature = "parallel"))]
    Serial,
}

impl WorkerPool {
    /// The pool of Rust callers: a rayon pool of [`instance_threads`] threads (with the
    /// `parallel` feature; else the calling thread), spawned from a scoped thread.
    pub fn new(name: &str) -> Result<Self, String> {
        #[cfg(feature = "parallel")]
        {
            let mut pool = None;
            std::thread::scope(|s| s.spawn(|| pool = Some(Self::spawn_rayon(name))).join())
                .map_err(|p| format!("internal error (panic): {}", panic_message(&*p)))?;
            pool.unwrap_or_else(|| Err("internal error: the thread did not run".into()))
        }
        #[cfg(not(feature = "parallel"))]
        {
            let _ = name;
            Ok(WorkerPool(Kind::Serial))
        }
    }

    /// A pool that runs the parallel loops on `exec`.
    pub fn with_executor(exec: BoxedExecutor) -> Self {
        WorkerPool(Kind::Executor(exec))
    }

    #[cfg(feature = "parallel")]
    fn spawn_rayon(name: &str) -> Result<Self, String> {
        let handles: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>> = Arc::default();
        let h = handles.clone();
        let prefix: String = format!("fmu-{}", name.chars().take(8).collect::<String>());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(instance_threads())
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
        Ok(WorkerPool(Kind::Rayon {
            pool: Some(pool),
            handles,
        }))
    }

    /// Runs f with the pool running the parallel loops it makes.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.0 {
            Kind::Executor(e) => par::install(e, f),
            #[cfg(feature = "parallel")]
            Kind::Rayon { pool: Some(p), .. } => p.install(f),
            #[cfg(feature = "parallel")]
            Kind::Rayon { pool: None, .. } => f(),
            #[cfg(not(feature = "parallel"))]
            Kind::Serial => f(),
        }
    }
}

#[cfg(feature = "parallel")]
impl Drop for WorkerPool {
    fn drop(&mut self) {
        if let Kind::Rayon { pool, handles } = &mut self.0 {
            drop(pool.take());
            let handles: Vec<_> = handles
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .drain(..)
                .collect();
            for h in handles {
                let _ = h.join();
            }
        }
    }
}
