//! Logging: where messages go ([`Logger`]), one message waiting for it ([`LogRecord`]) and an
//! instance's pending log with the debug-logging switches of fmi2SetDebugLogging
//! ([`PendingLog`]).
use super::status::{FmiError, FmiResult, Status};
use crate::fmi::model_description::LOG_CATEGORIES;
use std::cell::{Cell, RefCell};
use std::sync::Arc;

/// Where log messages go (the host's logger callback, behind the C layer).
pub trait Logger: Send + Sync {
    fn log(&self, status: Status, category: &str, message: &str);
}

/// A logger that drops everything.
pub struct NoLogger;
impl Logger for NoLogger {
    fn log(&self, _: Status, _: &str, _: &str) {}
}

/// One log message waiting to be handed to the host's logger.
#[derive(Clone, Debug, PartialEq)]
pub struct LogRecord {
    pub status: Status,
    pub category: &'static str,
    pub message: String,
}

/// Records kept at most between two flushes (a host that never returns control would
/// otherwise grow the buffer without bound); later ones are counted and reported.
const MAX_PENDING_LOG: usize = 1000;

/// The messages of an instance's current call and its debug-logging switches. The messages are
/// handed to the logger after the call has released the instance ([`PendingLog::take`]), so a
/// logger may call back into the instance.
pub(super) struct PendingLog {
    logger: Arc<dyn Logger>,
    records: RefCell<Vec<LogRecord>>,
    dropped: Cell<usize>,
    logging_on: bool,
    categories: [bool; LOG_CATEGORIES.len()],
}

impl PendingLog {
    pub(super) fn new(logger: Arc<dyn Logger>, logging_on: bool) -> Self {
        PendingLog {
            logger,
            records: RefCell::new(Vec::new()),
            dropped: Cell::new(0),
            logging_on,
            categories: [true; LOG_CATEGORIES.len()],
        }
    }

    fn category_on(&self, name: &str) -> bool {
        LOG_CATEGORIES
            .iter()
            .position(|(c, _)| *c == name)
            .is_some_and(|i| self.categories[i])
    }

    fn push(&self, status: Status, category: &'static str, message: String) {
        let mut log = self.records.borrow_mut();
        if log.len() < MAX_PENDING_LOG {
            log.push(LogRecord {
                status,
                category,
                message,
            });
        } else {
            self.dropped.set(self.dropped.get() + 1);
        }
    }

    /// The messages logged since the last call, in order (see [`super::Instance::take_log`]).
    pub(super) fn take(&self) -> Vec<LogRecord> {
        let mut out = std::mem::take(&mut *self.records.borrow_mut());
        let dropped = self.dropped.replace(0);
        if dropped > 0 {
            out.push(LogRecord {
                status: Status::Warning,
                category: "logStatusWarning",
                message: format!("{dropped} further log messages were dropped"),
            });
        }
        out
    }

    /// Hands the pending messages to the logger (see [`super::Instance::flush_log`]).
    pub(super) fn flush(&self) {
        for r in self.take() {
            self.logger.log(r.status, r.category, &r.message);
        }
    }

    /// The logger itself when debug logging of `category` is on: for messages that must reach
    /// the host while a call runs (the set-up's stages), not after it returns.
    pub(super) fn immediate(&self, category: &str) -> Option<Arc<dyn Logger>> {
        (self.logging_on && (self.category_on(category) || self.category_on("logAll")))
            .then(|| self.logger.clone())
    }

    /// Logs an event (category logEvents) when debug logging is on.
    pub(super) fn event(&self, msg: &str) {
        if self.logging_on && (self.category_on("logEvents") || self.category_on("logAll")) {
            self.push(Status::Ok, "logEvents", msg.to_string());
        }
    }

    pub(super) fn trace(&self, msg: &str) {
        if self.logging_on && self.category_on("logAll") {
            self.push(Status::Ok, "logAll", msg.to_string());
        }
    }

    /// Logs a warning (always: warnings are not debug messages).
    pub(super) fn warn(&self, msg: String) {
        self.push(Status::Warning, "logStatusWarning", msg);
    }

    /// Logs a warning at once, while the call runs (always, like [`PendingLog::warn`]): for
    /// what the host must hear before the work, not after it (a doStep of many minutes). The
    /// logger is called with the instance locked; a logger that calls back into the instance
    /// is refused by the C layer (ffi::guard), not deadlocked.
    pub(super) fn warn_now(&self, msg: &str) {
        self.logger.log(Status::Warning, "logStatusWarning", msg);
    }

    /// Logs an error of a call (always: errors are not debug messages).
    pub(super) fn report(&self, function: &str, e: &FmiError) {
        let category = match e.status() {
            Status::Warning | Status::Discard => "logStatusWarning",
            _ => "logStatusError",
        };
        self.push(e.status(), category, format!("{function}: {}", e.message()));
    }

    /// fmi2SetDebugLogging: debug logging on or off, for the given categories (none = all).
    pub(super) fn set_debug_logging(&mut self, on: bool, categories: &[String]) -> FmiResult<()> {
        let mut enabled = [categories.is_empty(); LOG_CATEGORIES.len()];
        for c in categories {
            let i = LOG_CATEGORIES
                .iter()
                .position(|(n, _)| n == c)
                .ok_or_else(|| {
                    FmiError::Invalid(format!(
                        "unknown log category '{c}' (known: {})",
                        LOG_CATEGORIES.map(|(n, _)| n).join(", ")
                    ))
                })?;
            enabled[i] = true;
        }
        self.logging_on = on;
        self.categories = enabled;
        Ok(())
    }
}
