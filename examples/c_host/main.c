/* A minimal FMI 2.0 co-simulation host in plain C: loads an FMU unpacked in a directory with
 * dlopen, steps it and prints the probe displacements (outputs named <probe>.ux/.uy/.uz).
 *
 *   c_host UNPACKED_FMU_DIR [STOP_TIME [STEP]]
 *
 * Uses only the official FMI 2.0 headers (vendor/fmi2). Exit status 0 on success. */
#define _XOPEN_SOURCE 700
#include <dlfcn.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define MAX_OUTPUTS 256

static char *read_file(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) { free(buf); buf = NULL; }
    if (buf) buf[n] = '\0';
    fclose(f);
    return buf;
}

/* Copies the value of attribute `name` found in [from, to) into out; 0 if absent. */
static int attr(const char *from, const char *to, const char *name, char *out, size_t size) {
    char key[64];
    snprintf(key, sizeof key, " %s=\"", name);
    const char *p = strstr(from, key);
    if (!p || (to && p >= to)) return 0;
    p += strlen(key);
    const char *e = strchr(p, '"');
    if (!e) return 0;
    size_t n = (size_t)(e - p) < size - 1 ? (size_t)(e - p) : size - 1;
    memcpy(out, p, n);
    out[n] = '\0';
    return 1;
}

/* file:// URI of an absolute path, percent-encoding every byte but unreserved ones and '/'. */
static void file_uri(const char *path, char *out, size_t size) {
    static const char hex[] = "0123456789ABCDEF";
    size_t n = (size_t)snprintf(out, size, "file://");
    for (const unsigned char *p = (const unsigned char *)path; *p && n + 4 < size; p++) {
        if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') ||
            strchr("/-._~", *p)) {
            out[n++] = (char)*p;
        } else {
            out[n++] = '%';
            out[n++] = hex[*p >> 4];
            out[n++] = hex[*p & 15];
        }
    }
    out[n] = '\0';
}

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s] %s (status %d): ", instance ? instance : "?", category ? category : "?", (int)status);
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

#define LOAD(name)                                                               \
    name##TYPE *name;                                                            \
    *(void **)(&name) = dlsym(lib, #name); /* the POSIX idiom for function pointers */ \
    if (!name) { fprintf(stderr, "symbol %s missing\n", #name); return 1; }

#define CHECK(call)                                                              \
    do {                                                                         \
        fmi2Status s_ = (call);                                                  \
        if (s_ != fmi2OK) { fprintf(stderr, "%s failed: status %d\n", #call, (int)s_); return 1; } \
    } while (0)

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s UNPACKED_FMU_DIR [STOP_TIME [STEP]]\n", argv[0]);
        return 2;
    }
    char dir[PATH_MAX];
    if (!realpath(argv[1], dir)) { perror(argv[1]); return 1; }
    char path[PATH_MAX + 512];
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    char *xml = read_file(path);
    if (!xml) { perror(path); return 1; }

    char guid[128], ident[256], stop_s[64] = "0.1", step_s[64] = "0.001";
    if (!attr(xml, NULL, "guid", guid, sizeof guid) ||
        !attr(xml, NULL, "modelIdentifier", ident, sizeof ident)) {
        fprintf(stderr, "%s: no guid or modelIdentifier\n", path);
        return 1;
    }
    const char *exp = strstr(xml, "<DefaultExperiment");
    if (exp) {
        attr(exp, NULL, "stopTime", stop_s, sizeof stop_s);
        attr(exp, NULL, "stepSize", step_s, sizeof step_s);
    }
    double stop = argc > 2 ? atof(argv[2]) : atof(stop_s);
    double step = argc > 3 ? atof(argv[3]) : atof(step_s);
    if (!(stop > 0) || !(step > 0)) { fprintf(stderr, "bad stop time or step\n"); return 2; }

    /* Probe outputs: <probe>.ux / .uy / .uz. */
    fmi2ValueReference vr[MAX_OUTPUTS];
    char names[MAX_OUTPUTS][128];
    size_t n = 0;
    for (const char *p = strstr(xml, "<ScalarVariable"); p && n < MAX_OUTPUTS;
         p = strstr(p + 1, "<ScalarVariable")) {
        const char *end = strstr(p, "</ScalarVariable>");
        char name[128], causality[32], ref[32];
        if (!attr(p, end, "name", name, sizeof name) || !attr(p, end, "causality", causality, sizeof causality) ||
            !attr(p, end, "valueReference", ref, sizeof ref))
            continue;
        size_t len = strlen(name);
        if (strcmp(causality, "output") == 0 && len > 3 && name[len - 3] == '.' && name[len - 2] == 'u') {
            vr[n] = (fmi2ValueReference)strtoul(ref, NULL, 10);
            snprintf(names[n], sizeof names[n], "%s", name);
            n++;
        }
    }
    free(xml);
    if (n == 0) { fprintf(stderr, "no probe outputs\n"); return 1; }

    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, ident);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "dlopen: %s\n", dlerror()); return 1; }
    LOAD(fmi2GetVersion)
    LOAD(fmi2Instantiate)
    LOAD(fmi2FreeInstance)
    LOAD(fmi2SetupExperiment)
    LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode)
    LOAD(fmi2DoStep)
    LOAD(fmi2GetReal)
    LOAD(fmi2GetRealStatus)
    LOAD(fmi2Terminate)

    char uri[3 * PATH_MAX + 64];
    snprintf(path, sizeof path, "%s/resources", dir);
    file_uri(path, uri, sizeof uri);
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    printf("FMI %s, model %s\n", fmi2GetVersion(), ident);
    fmi2Component c = fmi2Instantiate("c_host", fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2False);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 1; }
    CHECK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2True, stop));
    CHECK(fmi2EnterInitializationMode(c));
    CHECK(fmi2ExitInitializationMode(c));

    double values[MAX_OUTPUTS];
    printf("%-10s", "time");
    for (size_t k = 0; k < n; k++) printf(" %14s", names[k]);
    printf("\n");
    long steps = (long)(stop / step + 0.5);
    long every = steps / 10 > 0 ? steps / 10 : 1;
    double t = 0.0;
    for (long i = 0; i < steps; i++) {
        double h = (i == steps - 1) ? stop - t : step;
        if (h <= 0) break;
        CHECK(fmi2DoStep(c, t, h, fmi2True));
        t += h;
        if ((i + 1) % every == 0 || i == steps - 1) {
            CHECK(fmi2GetReal(c, vr, n, values));
            printf("%-10.5f", t);
            for (size_t k = 0; k < n; k++) printf(" %14.6e", values[k]);
            printf("\n");
        }
    }
    double last = -1.0;
    CHECK(fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &last));
    printf("last successful time %.9f\n", last);
    CHECK(fmi2Terminate(c));
    fmi2FreeInstance(c);
    dlclose(lib);
    return 0;
}
