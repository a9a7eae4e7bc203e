//! The threads of the C layer (part of `ffi`, the crate's only unsafe code): an FMU instance's
//! own worker threads ([`InstanceThreads`], the executor of its parallel loops) and the OS
//! thread that starts them ([`run_on_os_thread`]).
//!
//! Hosts unload the library after fmi2FreeInstance (and fmpy loads a fresh copy for every FMU),
//! so nothing may outlive an instance: no thread, no allocation, no thread-local destructor on
//! the host's threads. rayon's pools fail the second: its deques reclaim memory through
//! crossbeam-epoch, whose global collector and per-thread records are statics of the library
//! copy, never freed when it is unmapped (about 11 kB lost per load cycle under valgrind,
//! issue 27.5). These threads share only what the instance owns: they are joined and every
//! allocation freed in fmi2FreeInstance.
use crate::fmi::instance::panic_message;
use crate::physics::par::Executor;
use std::any::Any;
use std::ffi::c_void;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

/// The tasks of one parallel loop as the workers see them. `task` is the caller's closure with
/// its lifetime erased: valid only while the loop's `run` has not returned, which it does only
/// after withdrawing the job and waiting until no worker holds it ([`Withdraw`]).
#[derive(Clone, Copy)]
struct Job {
    task: &'static (dyn Fn(usize) + Sync),
    tasks: usize,
}

struct State {
    /// The loop being run, if any.
    job: Option<Job>,
    /// Loops published so far (a worker takes each one at most once).
    generation: u64,
    /// Workers running tasks of `job`.
    active: usize,
    /// Set when the instance is freed: the workers end.
    shutdown: bool,
}

struct Shared {
    state: Mutex<State>,
    /// Workers wait here for a loop (or the shutdown).
    wake: Condvar,
    /// The loop's caller waits here for the last active worker.
    idle: Condvar,
    /// The next task index to hand out.
    next: AtomicUsize,
    /// The first panic of a task, raised again on the loop's caller.
    panic: Mutex<Option<Box<dyn Any + Send>>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Shared {
    /// Runs tasks of `job` until all have been handed out; a panic is kept for the caller.
    fn claim(&self, job: Job) {
        let r = catch_unwind(AssertUnwindSafe(|| loop {
            let k = self.next.fetch_add(1, Ordering::SeqCst);
            if k >= job.tasks {
                break;
            }
            (job.task)(k);
        }));
        if let Err(p) = r {
            // The other tasks are still handed out and run; the loop fails as a whole.
            self.next.store(usize::MAX / 2, Ordering::SeqCst);
            lock(&self.panic).get_or_insert(p);
        }
    }
}

/// Withdraws the current job when dropped (also when the caller unwinds) and waits until no
/// worker runs its tasks: after this, no thread holds the job's erased reference.
struct Withdraw<'a>(&'a Shared);

impl Drop for Withdraw<'_> {
    fn drop(&mut self) {
        let mut st = lock(&self.0.state);
        st.job = None;
        while st.active > 0 {
            st = self.0.idle.wait(st).unwrap_or_else(|e| e.into_inner());
        }
    }
}

fn worker(shared: Arc<Shared>) {
    let mut seen = 0;
    loop {
        let job = {
            let mut st = lock(&shared.state);
            loop {
                if st.shutdown {
                    return;
                }
                if st.generation != seen {
                    seen = st.generation;
                    if let Some(job) = st.job {
                        st.active += 1;
                        break job;
                    }
                }
                st = shared.wake.wait(st).unwrap_or_else(|e| e.into_inner());
            }
        };
        shared.claim(job);
        let mut st = lock(&shared.state);
        st.active -= 1;
        if st.active == 0 {
            shared.idle.notify_all();
        }
    }
}

/// An instance's worker threads: `threads - 1` of them, plus the thread that calls into the
/// instance, which runs tasks too. Joined when dropped.
pub(super) struct InstanceThreads {
    shared: Arc<Shared>,
    workers: Vec<std::thread::JoinHandle<()>>,
}

impl InstanceThreads {
    /// Starts `threads - 1` workers named after the instance, from a short-lived OS thread
    /// ([`run_on_os_thread`]): never from the caller's thread.
    pub(super) fn start(name: &str, threads: usize) -> Result<Self, String> {
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                job: None,
                generation: 0,
                active: 0,
                shutdown: false,
            }),
            wake: Condvar::new(),
            idle: Condvar::new(),
            next: AtomicUsize::new(0),
            panic: Mutex::new(None),
        });
        let prefix: String = format!("fmu-{}", name.chars().take(8).collect::<String>());
        let mut pool = InstanceThreads {
            shared: shared.clone(),
            workers: Vec::new(),
        };
        let workers = &mut pool.workers;
        let started = run_on_os_thread(move || {
            for k in 1..threads.max(1) {
                let s = shared.clone();
                let h = std::thread::Builder::new()
                    .name(format!("{prefix}-{k}"))
                    .spawn(move || worker(s))
                    .map_err(|e| format!("cannot start worker thread {k} of {threads}: {e}"))?;
                workers.push(h);
            }
            Ok::<(), String>(())
        });
        // On failure the threads already started are joined by `pool`'s drop.
        started.and_then(|r| r)?;
        Ok(pool)
    }
}

impl Executor for InstanceThreads {
    fn threads(&self) -> usize {
        self.workers.len() + 1
    }

    fn run(&self, tasks: usize, task: &(dyn Fn(usize) + Sync)) {
        if self.workers.is_empty() || tasks <= 1 {
            return (0..tasks).for_each(task);
        }
        // SAFETY: the reference is handed to the workers only inside `Job`, which `Withdraw`
        // takes back before this function returns or unwinds, after waiting until no worker
        // is running its tasks; `task` outlives this call, so it outlives every use.
        let task: &'static (dyn Fn(usize) + Sync) = unsafe { std::mem::transmute(task) };
        let job = Job { task, tasks };
        let shared = &*self.shared;
        shared.next.store(0, Ordering::SeqCst);
        {
            let mut st = lock(&shared.state);
            st.job = Some(job);
            st.generation += 1;
        }
        let withdraw = Withdraw(shared);
        shared.wake.notify_all();
        shared.claim(job);
        drop(withdraw);
        if let Some(p) = lock(&shared.panic).take() {
            std::panic::resume_unwind(p);
        }
    }
}

impl Drop for InstanceThreads {
    fn drop(&mut self) {
        lock(&self.shared.state).shutdown = true;
        self.shared.wake.notify_all();
        for h in self.workers.drain(..) {
            let _ = h.join();
        }
    }
}

/// Runs `f` on a new OS thread created with `pthread_create` and waits for it to end.
///
/// Used to start an instance's worker threads off the host's thread: `std::thread::spawn`
/// registers a thread-local destructor (std's spawn hooks) on the *calling* thread with
/// `__cxa_thread_atexit_impl`, and glibc keeps a library loaded while any thread holds one of
/// its TLS destructors. Spawned from the host's thread (which typically never exits), the
/// workers pinned every loaded copy of this library: `dlclose` never unmapped it. The thread
/// made here ends (running its TLS destructors) before this returns.
#[cfg(unix)]
pub(super) fn run_on_os_thread<R: Send>(f: impl FnOnce() -> R + Send) -> Result<R, String> {
    type Job<'a> = Option<Box<dyn FnOnce() + Send + 'a>>;
    extern "C" fn start(p: *mut c_void) -> *mut c_void {
        // SAFETY: p is the `Job` below, which the creating thread keeps alive and does not
        // touch until pthread_join has returned.
        let job = unsafe { &mut *(p as *mut Job<'static>) };
        if let Some(f) = job.take() {
            // f catches its own panics; this is the last line of defence before the C frame.
            let _ = catch_unwind(AssertUnwindSafe(f));
        }
        std::ptr::null_mut()
    }
    let mut out: Option<std::thread::Result<R>> = None;
    let slot = &mut out;
    let mut job: Job<'_> = Some(Box::new(move || {
        *slot = Some(catch_unwind(AssertUnwindSafe(f)));
    }));
    // SAFETY: plain pthread calls; the job outlives the thread (joined below before `job` is
    // dropped), and a failed join of a joinable thread we just created cannot be recovered
    // from soundly (the thread could still use `job`), hence the abort.
    unsafe {
        let mut tid: libc::pthread_t = std::mem::zeroed();
        let rc = libc::pthread_create(
            &mut tid,
            std::ptr::null(),
            start,
            &mut job as *mut Job<'_> as *mut c_void,
        );
        if rc != 0 {
            return Err(format!(
                "cannot start a thread: {}",
                std::io::Error::from_raw_os_error(rc)
            ));
        }
        if libc::pthread_join(tid, std::ptr::null_mut()) != 0 {
            std::process::abort();
        }
    }
    drop(job);
    match out {
        Some(Ok(r)) => Ok(r),
        Some(Err(p)) => Err(format!("internal error (panic): {}", panic_message(&*p))),
        None => Err("internal error: the thread did not run".into()),
    }
}

/// Elsewhere: a scoped std thread (no TLS-destructor pinning to avoid).
#[cfg(not(unix))]
pub(super) fn run_on_os_thread<R: Send>(f: impl FnOnce() -> R + Send) -> Result<R, String> {
    std::thread::scope(|s| s.spawn(f).join())
        .map_err(|p| format!("internal error (panic): {}", panic_message(&*p)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::par::{install, map, BoxedExecutor, ParMut, Producer};

    #[test]
    fn every_task_runs_once_on_the_instance_threads() {
        for threads in [1, 2, 3, 5] {
            let t = InstanceThreads::start("unit", threads).unwrap();
            assert_eq!(t.threads(), threads);
            let exec: BoxedExecutor = Box::new(t);
            for n in [0, 1, 2, 17, 1000] {
                let mut v = vec![0usize; n];
                install(&exec, || {
                    ParMut(&mut v[..])
                        .enumerate()
                        .for_each(|(i, x)| *x += i + 1)
                });
                assert!(
                    v.iter().enumerate().all(|(i, x)| *x == i + 1),
                    "{threads} {n}"
                );
            }
            let names: Vec<Option<String>> = install(&exec, || {
                map(&(0..64).collect::<Vec<_>>(), |_| {
                    std::thread::sleep(std::time::Duration::from_micros(200));
                    std::thread::current().name().map(str::to_string)
                })
            });
            if threads > 1 {
                assert!(
                    names.iter().any(|n| n.as_deref() == Some("fmu-unit-1")),
                    "{names:?}"
                );
            }
        }
    }

    #[test]
    fn a_panicking_task_fails_the_loop_and_the_threads_go_on() {
        let exec: BoxedExecutor = Box::new(InstanceThreads::start("panic", 3).unwrap());
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let r = catch_unwind(AssertUnwindSafe(|| {
            install(&exec, || {
                map(&(0..100).collect::<Vec<usize>>(), |&k| {
                    if k == 37 {
                        panic!("task 37")
                    }
                    k
                })
            })
        }));
        std::panic::set_hook(prev);
        assert_eq!(panic_message(&*r.unwrap_err()), "task 37");
        let v = install(&exec, || map(&(0..100).collect::<Vec<usize>>(), |&k| k * 2));
        assert_eq!(v[99], 198);
    }
}
