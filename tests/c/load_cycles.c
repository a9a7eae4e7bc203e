/* A C host that loads the FMU's library, runs an instance and unloads the library, CYCLES
 * times over (issue 27.5): dlopen, fmi2Instantiate, fmi2SetupExperiment, enter and exit
 * initialisation mode, 3 fmi2DoStep, fmi2Terminate, fmi2FreeInstance, dlclose. Run under
 * valgrind by tests/suite/leak_check.rs: nothing may be lost per cycle.
 *
 *   load_cycles LIBRARY GUID RESOURCE_URI CYCLES
 *
 * Uses only the official FMI 2.0 headers (vendor/fmi2). Exit status 0 when every call
 * returned fmi2OK. */
#define _XOPEN_SOURCE 700
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    if (status == fmi2OK) return;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s %d %s] ", name, (int)status, category);
    vfprintf(stderr, message, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

#define CHECK(call)                                                      \
    do {                                                                 \
        fmi2Status s_ = (call);                                          \
        if (s_ != fmi2OK) {                                              \
            fprintf(stderr, "cycle %d: %s returned %d\n", k, #call, s_); \
            return 1;                                                    \
        }                                                                \
    } while (0)

/* Resolves fmi2<name> into a variable of type fmi2<name>TYPE * (through memcpy: ISO C has no
 * conversion from an object pointer to a function pointer; POSIX guarantees the bits). */
#define SYM(name)                                          \
    fmi2##name##TYPE *name;                                \
    {                                                      \
        void *p_ = dlsym(lib, "fmi2" #name);               \
        if (!p_) {                                         \
            fprintf(stderr, "missing symbol fmi2" #name "\n"); \
            return 1;                                      \
        }                                                  \
        memcpy(&name, &p_, sizeof name);                   \
    }

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: load_cycles LIBRARY GUID RESOURCE_URI CYCLES\n");
        return 2;
    }
    int cycles = atoi(argv[4]);
    fmi2CallbackFunctions cb = {logger, NULL, NULL, NULL, NULL};
    for (int k = 0; k < cycles; k++) {
        void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
        if (!lib) {
            fprintf(stderr, "dlopen: %s\n", dlerror());
            return 1;
        }
        SYM(Instantiate)
        SYM(SetupExperiment)
        SYM(EnterInitializationMode)
        SYM(ExitInitializationMode)
        SYM(DoStep)
        SYM(Terminate)
        SYM(FreeInstance)
        fmi2Component c = Instantiate("cycle", fmi2CoSimulation, argv[2], argv[3], &cb,
                                      fmi2False, fmi2False);
        if (!c) {
            fprintf(stderr, "cycle %d: fmi2Instantiate failed\n", k);
            return 1;
        }
        CHECK(SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
        CHECK(EnterInitializationMode(c));
        CHECK(ExitInitializationMode(c));
        for (int s = 0; s < 3; s++) CHECK(DoStep(c, s * 0.002, 0.002, fmi2True));
        CHECK(Terminate(c));
        FreeInstance(c);
        if (dlclose(lib) != 0) {
            fprintf(stderr, "dlclose: %s\n", dlerror());
            return 1;
        }
    }
    printf("%d load cycles done\n", cycles);
    return 0;
}
