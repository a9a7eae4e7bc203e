/* A variadic FMI 2.0 logger for the Rust host tests (Rust cannot define variadic functions on
 * stable): formats the message like a C host would and hands the result to a plain callback. */
#include <stdarg.h>
#include <stdio.h>
#include "fmi2FunctionTypes.h"

typedef void (*shim_sink)(fmi2ComponentEnvironment env, fmi2String instanceName,
                          int status, fmi2String category, fmi2String message);

static shim_sink sink;

void shim_set_sink(shim_sink s) { sink = s; }

void shim_logger(fmi2ComponentEnvironment env, fmi2String instanceName, fmi2Status status,
                 fmi2String category, fmi2String message, ...) {
    char buf[8192];
    va_list ap;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap);
    va_end(ap);
    if (sink) sink(env, instanceName, (int)status, category, buf);
}
