//! Data-parallel loops over particle arrays, one source for every way they run:
//! `par_iter_mut!(a).zip(par_iter_mut!(b)).enumerate().for_each(f)` and [`map`]. Every loop
//! writes only its own element (gather form), so results do not depend on the thread count or
//! on how the range is split.
//!
//! Where a loop runs: on the [`Executor`] installed on the calling thread ([`install`]: an FMU
//! instance's own threads, which use no library-global state, so that nothing outlives the
//! instance when a host unloads the library), else on rayon's current pool (feature
//! `parallel`), else serially.
use std::sync::Mutex;

/// Runs the tasks of a parallel loop on a set of threads.
pub trait Executor: Send + Sync {
    /// Threads that run tasks, the calling thread included (>= 1).
    fn threads(&self) -> usize;
    /// Calls `task(k)` exactly once for every k in 0..tasks, on the executor's threads and the
    /// calling thread, and returns when every call has returned. A task's panic is raised
    /// again on the calling thread after all tasks have ended.
    fn run(&self, tasks: usize, task: &(dyn Fn(usize) + Sync));
}

/// An executor as installed on a thread (a sized handle for the thread-local slot).
pub type BoxedExecutor = Box<dyn Executor>;

scoped_tls::scoped_thread_local!(
    /// The executor of the loops run by this thread, for the duration of [`install`]. A plain
    /// pointer slot: it registers no thread-local destructor, which would keep a dlopen'ed
    /// library loaded as long as the host's thread lives.
    static CURRENT: BoxedExecutor
);

/// Runs `f` with `exec` running the parallel loops `f` makes on this thread.
pub fn install<R>(exec: &BoxedExecutor, f: impl FnOnce() -> R) -> R {
    CURRENT.set(exec, f)
}

/// Parts a loop is split into per thread: enough for the threads to balance uneven particles
/// (a clamp's or a surface's particles have fewer bonds), few enough that handing them out costs
/// nothing next to the work.
const PARTS_PER_THREAD: usize = 4;

/// A range of elements that can be split and iterated: a slice, or several zipped, with or
/// without their indices.
pub trait Producer: Send + Sized {
    type Item;
    type IntoIter: Iterator<Item = Self::Item>;
    fn len(&self) -> usize;
    /// Whether there are no elements.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The first `mid` elements and the rest (mid <= len).
    fn split_at(self, mid: usize) -> (Self, Self);
    fn into_iter(self) -> Self::IntoIter;

    /// The elements of `self` and `other` side by side (as long as the shorter).
    fn zip<B: Producer>(self, other: B) -> Zip<Self, B> {
        Zip(self, other)
    }
    /// Each element with its index.
    fn enumerate(self) -> Enumerate<Self> {
        Enumerate {
            inner: self,
            offset: 0,
        }
    }
    /// Calls `f` on every element, in parallel (see the module's documentation for where).
    fn for_each<F: Fn(Self::Item) + Sync + Send>(self, f: F) {
        if CURRENT.is_set() {
            CURRENT.with(|e| run_on(&**e, self, &f))
        } else {
            fallback(self, &f)
        }
    }
}

/// Mutable elements of a slice (what `par_iter_mut!` makes).
pub struct ParMut<'a, T>(pub &'a mut [T]);

impl<'a, T: Send> Producer for ParMut<'a, T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn len(&self) -> usize {
        self.0.len()
    }
    fn split_at(self, mid: usize) -> (Self, Self) {
        let (a, b) = self.0.split_at_mut(mid);
        (ParMut(a), ParMut(b))
    }
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter_mut()
    }
}

/// Shared elements of a slice.
pub struct ParRef<'a, T>(pub &'a [T]);

impl<'a, T: Sync> Producer for ParRef<'a, T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn len(&self) -> usize {
        self.0.len()
    }
    fn split_at(self, mid: usize) -> (Self, Self) {
        let (a, b) = self.0.split_at(mid);
        (ParRef(a), ParRef(b))
    }
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

/// Two producers side by side.
pub struct Zip<A, B>(A, B);

impl<A: Producer, B: Producer> Producer for Zip<A, B> {
    type Item = (A::Item, B::Item);
    type IntoIter = std::iter::Zip<A::IntoIter, B::IntoIter>;
    fn len(&self) -> usize {
        self.0.len().min(self.1.len())
    }
    fn split_at(self, mid: usize) -> (Self, Self) {
        let (a0, a1) = self.0.split_at(mid);
        let (b0, b1) = self.1.split_at(mid);
        (Zip(a0, b0), Zip(a1, b1))
    }
    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter().zip(self.1.into_iter())
    }
}

/// A producer with the indices of its elements.
pub struct Enumerate<P> {
    inner: P,
    offset: usize,
}

impl<P: Producer> Producer for Enumerate<P> {
    type Item = (usize, P::Item);
    type IntoIter = std::iter::Zip<std::ops::Range<usize>, P::IntoIter>;
    fn len(&self) -> usize {
        self.inner.len()
    }
    fn split_at(self, mid: usize) -> (Self, Self) {
        let (a, b) = self.inner.split_at(mid);
        (
            Enumerate {
                inner: a,
                offset: self.offset,
            },
            Enumerate {
                inner: b,
                offset: self.offset + mid,
            },
        )
    }
    fn into_iter(self) -> Self::IntoIter {
        let n = self.inner.len();
        (self.offset..self.offset + n).zip(self.inner.into_iter())
    }
}

/// `f` of every element of `items`, in order, computed in parallel.
pub fn map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync + Send) -> Vec<R> {
    let mut out: Vec<Option<R>> = items.iter().map(|_| None).collect();
    ParMut(&mut out[..])
        .zip(ParRef(items))
        .for_each(|(o, t)| *o = Some(f(t)));
    out.into_iter().flatten().collect()
}

/// Elements per part of [`sum`]: its parts, and so its bits, do not depend on the thread count.
const SUM_CHUNK: usize = 4096;

/// The sum of `f(i)` for i in 0..n, in parallel: each part of `SUM_CHUNK` consecutive indices
/// summed in order, the parts' sums added in order. The same bits on any number of threads (not
/// those of one sum in order over 0..n).
pub fn sum(n: usize, f: impl Fn(usize) -> f64 + Sync + Send) -> f64 {
    let starts: Vec<usize> = (0..n).step_by(SUM_CHUNK).collect();
    map(&starts, |&s| {
        (s..(s + SUM_CHUNK).min(n)).map(&f).sum::<f64>()
    })
    .into_iter()
    .sum()
}

/// Splits `p` into `parts` nearly equal consecutive parts.
fn split<P: Producer>(p: P, parts: usize) -> Vec<P> {
    let mut out = Vec::with_capacity(parts);
    let mut rest = p;
    for k in (1..parts).rev() {
        // Of the remaining elements, 1 / (k + 1) go to this part.
        let take = rest.len() / (k + 1);
        let (a, b) = rest.split_at(take);
        out.push(a);
        rest = b;
    }
    out.push(rest);
    out
}

/// Runs a loop on an executor: the range is cut into parts that its threads take in turn.
fn run_on<P: Producer, F: Fn(P::Item) + Sync>(e: &dyn Executor, p: P, f: &F) {
    let parts = (e.threads() * PARTS_PER_THREAD).min(p.len());
    if e.threads() <= 1 || parts <= 1 {
        return p.into_iter().for_each(f);
    }
    let parts: Vec<Mutex<Option<P>>> = split(p, parts)
        .into_iter()
        .map(|p| Mutex::new(Some(p)))
        .collect();
    // A loop inside a task runs serially on the task's thread: the executor is busy with this
    // loop (its `run` is not re-entrant), and a worker thread must not fall back to rayon's
    // global pool, whose threads and crossbeam-epoch globals would outlive an FMU instance.
    let serial: BoxedExecutor = Box::new(Serial);
    e.run(parts.len(), &|k| {
        let part = parts[k].lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(part) = part {
            CURRENT.set(&serial, || part.into_iter().for_each(f));
        }
    });
}

/// The executor of loops nested in a task of another loop: the task's own thread.
struct Serial;

impl Executor for Serial {
    fn threads(&self) -> usize {
        1
    }
    fn run(&self, tasks: usize, task: &(dyn Fn(usize) + Sync)) {
        (0..tasks).for_each(task)
    }
}

/// Without an installed executor: rayon's current pool, split in halves with `rayon::join`.
#[cfg(feature = "parallel")]
fn fallback<P: Producer, F: Fn(P::Item) + Sync>(p: P, f: &F) {
    fn halves<P: Producer, F: Fn(P::Item) + Sync>(p: P, f: &F, parts: usize) {
        if parts <= 1 || p.len() <= 1 {
            return p.into_iter().for_each(f);
        }
        let mid = p.len() / 2;
        let (a, b) = p.split_at(mid);
        rayon::join(
            || halves(a, f, parts / 2),
            || halves(b, f, parts - parts / 2),
        );
    }
    let threads = rayon::current_num_threads();
    if threads <= 1 {
        // One thread: serially here. A join from outside the pool would hand each half to the
        // pool's one thread and wait for it (two context switches per loop, 8 % of case 3).
        return p.into_iter().for_each(f);
    }
    halves(p, f, threads * PARTS_PER_THREAD)
}

/// Without an installed executor and without rayon: serially.
#[cfg(not(feature = "parallel"))]
fn fallback<P: Producer, F: Fn(P::Item) + Sync>(p: P, f: &F) {
    p.into_iter().for_each(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// An executor that runs the tasks in reverse order on the calling thread, counting runs.
    struct Backwards(usize, AtomicUsize);
    impl Executor for Backwards {
        fn threads(&self) -> usize {
            self.0
        }
        fn run(&self, tasks: usize, task: &(dyn Fn(usize) + Sync)) {
            self.1.fetch_add(1, Ordering::Relaxed);
            for k in (0..tasks).rev() {
                task(k)
            }
        }
    }

    fn fill(a: &mut [usize], b: &mut [f64]) {
        ParMut(a)
            .zip(ParMut(b))
            .enumerate()
            .for_each(|(i, (x, y))| {
                *x = i * i;
                *y = i as f64 * 0.5;
            });
    }

    #[test]
    fn sums_have_the_same_bits_however_the_loop_runs() {
        // Terms of mixed magnitude, so that the order of the additions shows in the bits.
        let term = |i: usize| ((i * 7919) % 1000) as f64 * 10f64.powi((i % 17) as i32 - 8);
        for n in [0, 1, 4095, 4096, 4097, 3 * 4096 + 5] {
            // The definition: each chunk of SUM_CHUNK in order, then the chunks' sums in order.
            let want: f64 = (0..n)
                .step_by(SUM_CHUNK)
                .map(|s| (s..(s + SUM_CHUNK).min(n)).map(term).sum::<f64>())
                .sum();
            assert_eq!(sum(n, term).to_bits(), want.to_bits(), "n {n}");
            for threads in [1, 2, 3, 8] {
                let e: BoxedExecutor = Box::new(Backwards(threads, AtomicUsize::new(0)));
                let got = install(&e, || sum(n, term));
                assert_eq!(got.to_bits(), want.to_bits(), "n {n}, {threads} threads");
            }
        }
        // And the chunking matters: one sum in order over many terms has other bits.
        let n = 3 * 4096 + 5;
        let serial: f64 = (0..n).map(term).sum();
        assert_ne!(serial.to_bits(), sum(n, term).to_bits());
    }

    #[test]
    fn every_element_once_with_its_index_however_the_loop_runs() {
        for n in [0, 1, 2, 7, 100, 1001] {
            let want: Vec<usize> = (0..n).map(|i| i * i).collect();
            let (mut a, mut b) = (vec![0; n], vec![0.0; n + 3]);
            fill(&mut a, &mut b);
            assert_eq!(a, want);
            for threads in [1, 2, 3, 8] {
                let e: BoxedExecutor = Box::new(Backwards(threads, AtomicUsize::new(0)));
                let (mut a2, mut b2) = (vec![0; n], vec![0.0; n + 3]);
                install(&e, || fill(&mut a2, &mut b2));
                assert_eq!(a2, want, "n {n}, {threads} threads");
                // Zip is as long as the shorter: the extra elements are untouched.
                assert_eq!(b2, b, "n {n}, {threads} threads");
            }
        }
    }

    #[test]
    fn map_keeps_the_order_and_runs_on_the_installed_executor() {
        let items: Vec<u32> = (0..50).collect();
        let e: BoxedExecutor = Box::new(Backwards(2, AtomicUsize::new(0)));
        let out = install(&e, || map(&items, |x| x * 3));
        assert_eq!(out, items.iter().map(|x| x * 3).collect::<Vec<_>>());
        assert_eq!(map(&items, |x| x + 1)[49], 50);
    }

    #[test]
    fn a_loop_nested_in_a_task_runs_serially_on_the_tasks_thread() {
        // The sbp closure solves its axes side by side, each with loops of its own: those must
        // not re-enter the busy executor, nor fall back to rayon's global pool on a worker.
        /// Runs the tasks on the calling thread, counting the loops it runs.
        struct Counting(std::sync::Arc<AtomicUsize>);
        impl Executor for Counting {
            fn threads(&self) -> usize {
                3
            }
            fn run(&self, tasks: usize, task: &(dyn Fn(usize) + Sync)) {
                self.0.fetch_add(1, Ordering::Relaxed);
                (0..tasks).for_each(task)
            }
        }
        let runs = std::sync::Arc::new(AtomicUsize::new(0));
        let e: BoxedExecutor = Box::new(Counting(runs.clone()));
        let rows: Vec<usize> = (0..5).collect();
        let sums = install(&e, || {
            map(&rows, |&r| {
                let inner: Vec<usize> = (0..100).map(|k| k * r).collect();
                map(&inner, |x| x + 1).iter().sum::<usize>()
            })
        });
        let want: Vec<usize> = rows.iter().map(|r| 4950 * r + 100).collect();
        assert_eq!(sums, want);
        assert_eq!(
            runs.load(Ordering::Relaxed),
            1,
            "the executor ran only the outer loop"
        );
    }

    #[test]
    fn split_parts_are_nearly_equal() {
        let mut v = [0u8; 10];
        let parts = split(ParMut(&mut v[..]), 4);
        let lens: Vec<usize> = parts.iter().map(|p| p.len()).collect();
        assert_eq!(lens, vec![2, 2, 3, 3]);
    }
}
