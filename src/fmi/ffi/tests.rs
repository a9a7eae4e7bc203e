//! Unit tests of the C layer: the bootstrap thread of the worker pools and the panic boundary.
use super::threads::run_on_os_thread;
use super::*;
use crate::fmi::instance::NoLogger;

#[test]
fn run_on_os_thread_returns_the_result_on_another_thread() {
    let me = std::thread::current().id();
    let mut touched = false;
    let r = run_on_os_thread(|| {
        touched = true;
        (std::thread::current().id() != me, 42)
    });
    assert_eq!(r, Ok((true, 42)));
    assert!(touched, "the closure may borrow the caller's data");
    let prev = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let e = run_on_os_thread(|| -> u8 { panic!("boom") });
    std::panic::set_hook(prev);
    assert!(e.unwrap_err().contains("boom"));
}

struct Capture(Mutex<Vec<(Status, String)>>);
impl Logger for Capture {
    fn log(&self, status: Status, _: &str, message: &str) {
        self.0.lock().unwrap().push((status, message.to_string()));
    }
}

/// The panic boundary: a panic becomes fmi2Fatal with a message, then every call fails.
#[test]
fn panics_become_fatal() {
    let dir = std::env::temp_dir().join(format!("mps-ffi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = crate::Scene::from_json(include_str!("../../../tests/data/small3d.json")).unwrap();
    std::fs::write(dir.join("scene.json"), scene.to_json()).unwrap();
    let uri = format!("file://{}", dir.display());
    let guid = crate::fmi::model_description::guid(&scene);
    let inst =
        Instance::instantiate("t", true, &guid, Some(&uri), Arc::new(NoLogger), false).unwrap();
    let capture = Arc::new(Capture(Mutex::new(vec![])));
    let comp = Component {
        logger: capture.clone(),
        setup: inst.setup_control(),
        inst: Mutex::new(inst),
        fatal: AtomicBool::new(false),
        owner: AtomicUsize::new(0),
    };
    let prev = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let s = guard(&comp, "fmi2Test", |_| panic!("boom"));
    std::panic::set_hook(prev);
    assert_eq!(s, fmi2Status::fmi2Fatal);
    assert_eq!(guard(&comp, "fmi2Test", |_| Ok(())), fmi2Status::fmi2Error);
    let log = capture.0.lock().unwrap();
    assert_eq!(log[0].0, Status::Fatal);
    assert!(
        log[0].1.contains("panic") && log[0].1.contains("boom"),
        "{log:?}"
    );
    assert!(log[1].1.contains("unusable"), "{log:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A call made from within a running call on the same thread (the host's logger calling back
/// during a set-up message) is refused with fmi2Error instead of deadlocking on the lock.
#[test]
fn a_reentrant_call_is_refused_not_deadlocked() {
    let dir = std::env::temp_dir().join(format!("mps-ffi-reenter-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = crate::Scene::from_json(include_str!("../../../tests/data/small3d.json")).unwrap();
    std::fs::write(dir.join("scene.json"), scene.to_json()).unwrap();
    let uri = format!("file://{}", dir.display());
    let guid = crate::fmi::model_description::guid(&scene);
    let inst =
        Instance::instantiate("t", true, &guid, Some(&uri), Arc::new(NoLogger), false).unwrap();
    let capture = Arc::new(Capture(Mutex::new(vec![])));
    let comp = Component {
        logger: capture.clone(),
        setup: inst.setup_control(),
        inst: Mutex::new(inst),
        fatal: AtomicBool::new(false),
        owner: AtomicUsize::new(0),
    };
    let inner = std::cell::Cell::new(fmi2Status::fmi2OK);
    let outer = guard(&comp, "fmi2Outer", |_| {
        inner.set(guard(&comp, "fmi2Inner", |_| Ok(())));
        Ok(())
    });
    assert_eq!(
        (outer, inner.get()),
        (fmi2Status::fmi2OK, fmi2Status::fmi2Error)
    );
    let log = capture.0.lock().unwrap();
    assert!(
        log[0].1.contains("fmi2Inner") && log[0].1.contains("within a call"),
        "{log:?}"
    );
    // After the outer call the instance takes calls again.
    drop(log);
    assert_eq!(guard(&comp, "fmi2Next", |_| Ok(())), fmi2Status::fmi2OK);
    std::fs::remove_dir_all(&dir).ok();
}
