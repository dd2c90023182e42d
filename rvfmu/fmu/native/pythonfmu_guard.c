/* The pythonfmu FMU's binary on Linux: pythonfmu's own library, with the two things it cannot
 * do for the reducer slave (rvfmu/fmu/slave.py) done around it.
 *
 * pythonfmu 0.7.0 gives a Python slave two outcomes of a step, done (fmi2OK) or not
 * (fmi2Discard, after which fmi2GetBooleanStatus(fmi2Terminated) says true; an exception is
 * fmi2Fatal and leaves an instance that cannot be freed safely), and it passes the slave's log
 * messages to the host only when the host switched logging on.  A refused input then ends an
 * fmpy run early without a word: fmpy (0.3.32) stops on a discarded step with fmi2Terminated
 * true without raising, and nothing is logged at its default logging.  docs/model.md section 8
 * wants the host to fail and to learn why, as the native FMU does it.  So this library is the
 * FMU's binaries/linux64/RVReducer.so, with pythonfmu's library beside it
 * (libpythonfmu-export.so).  It opens that library by its full path (never by its soname:
 * a process that ran another pythonfmu FMU before, whose folder a host such as fmpy has
 * deleted since, holds a library of that soname, and the dynamic loader would hand this
 * FMU that one, with the other FMU's state) and passes every fmi2 function on to it, except
 * these:
 *
 *   fmi2Instantiate      pythonfmu's instance always logs, to this library's logger, which
 *                        passes warnings and errors to the host's logger whatever the host's
 *                        logging, and messages of status fmi2OK only with logging on (as the
 *                        native FMU, rvfmu/fmu/native/fmi2Functions.c);
 *   fmi2SetDebugLogging  switches those categories for the host, as the native FMU;
 *   fmi2DoStep           a step pythonfmu discards (the slave refused its inputs and logged
 *                        why with status fmi2Error) returns fmi2Error: no retry can make such
 *                        an input valid, and the simulation has ended; every later step
 *                        returns fmi2Error with the same reason, until fmi2Reset;
 *   fmi2GetBooleanStatus fmi2Terminated says whether it has ended (pythonfmu's says true
 *                        after any discarded step, and after fmi2Reset too);
 *   fmi2Reset            forgets that;
 *   fmi2FreeInstance     frees this library's record of the instance.
 *
 * And one thing at exit.  pythonfmu 0.7.0 releases its interpreter state (the static
 * shared_ptr `pyState` of its PySlaveInstance.cpp, made at the first fmi2Instantiate) twice
 * when a process exits with its library still loaded, as fmpy leaves it after a simulation that
 * raised: exit() runs the static's destructor, which frees the state but leaves the pointer,
 * and then the library's unload function (onLibraryUnload -> finalizePythonInterpreter)
 * decrements the count of that freed block again.  valgrind reports the use after free; glibc
 * aborted one host in about 60 ("corrupted double-linked list") when the freed block had gone
 * to a bin whose link it then broke.  On a dlclose the order is the other way round and
 * nothing is wrong.  So right after loading pythonfmu's library, this library registers an
 * exit handler, which runs before the static's destructor (handlers run in the reverse order
 * of their registration) and calls finalizePythonInterpreter once: it empties `pyState` before
 * it releases it, and the two later releases then find it empty.  That handler must still be
 * there at exit when the host unloaded this library before (fmpy's simulate_fmu frees it after
 * every run): pythonfmu's library holds C++ objects of unique binding, so the dynamic loader
 * never unloads it, and its double release comes at exit all the same (valgrind: a host that
 * runs simulate_fmu twice).  This library would be gone by then, its handler run at the dlclose
 * with nothing to release (a handler must not end the interpreter there: a native host may load
 * the FMU again).  So this library stays loaded as pythonfmu's does (RTLD_NODELETE), and its
 * handler runs at exit.
 *
 * The instances' records are kept in a list under a mutex (hosts may step instances in
 * threads); pythonfmu's component is the host's handle, unchanged.  POSIX only: on Windows the
 * FMU carries pythonfmu's own DLL.
 */
#define _GNU_SOURCE   /* dladdr */
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define MESSAGE_SIZE 2048

enum { LOG_ALL, LOG_WARNING, LOG_DISCARD, LOG_ERROR, LOG_FATAL, CATEGORIES };
static const char *const CATEGORY_NAMES[CATEGORIES] = {
    "logAll", "logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal"};

/* One instance: the host's logger, what the host wants logged, the reason it ended. */
typedef struct Guard {
    struct Guard *next;
    fmi2Component component;                  /* pythonfmu's, the host's handle */
    char name[256];                           /* the instance's name, for the host's logger */
    fmi2CallbackFunctions host;               /* the host's callbacks */
    fmi2CallbackFunctions mine;               /* pythonfmu keeps a pointer to these */
    int logging[CATEGORIES];
    int stepping;                             /* inside fmi2DoStep: an error message is kept */
    char reason[MESSAGE_SIZE];                /* the last error a step logged */
    char ended[MESSAGE_SIZE];                 /* why the simulation ended; empty while it runs */
} Guard;

static Guard *guards = NULL;
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;

static Guard *find(fmi2Component c) {
    Guard *g;
    pthread_mutex_lock(&lock);
    for (g = guards; g && g->component != c; g = g->next) continue;
    pthread_mutex_unlock(&lock);
    return g;
}

/* pythonfmu's library: PYTHONFMU_LIBRARY in this library's folder (the build names it,
 * rvfmu/fmu/build.py), opened once. */
#ifndef PYTHONFMU_LIBRARY
#define PYTHONFMU_LIBRARY "libpythonfmu-export.so"
#endif
static void *library = NULL;
static char library_error[MESSAGE_SIZE] = "";
static pthread_once_t library_once = PTHREAD_ONCE_INIT;
static void (*release_python)(void) = NULL;   /* pythonfmu's finalizePythonInterpreter */

/* At exit, or when this library is unloaded: pythonfmu's interpreter state released once, by
 * pythonfmu's own function, while its library is still loaded (module doc). */
static void release_at_exit(void) {
    if (library && release_python) release_python();
    release_python = NULL;
}

static void open_library(void) {
    Dl_info self;
    char path[4096];
    char *slash;
    const char *why;
    if (!dladdr((void *)&open_library, &self) || !self.dli_fname
        || strlen(self.dli_fname) + sizeof PYTHONFMU_LIBRARY >= sizeof path) {
        strcpy(library_error, "the FMU's library cannot find its own folder");
        return;
    }
    strcpy(path, self.dli_fname);
    slash = strrchr(path, '/');
    strcpy(slash ? slash + 1 : path, PYTHONFMU_LIBRARY);
    library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        why = dlerror();
        snprintf(library_error, sizeof library_error, "cannot load pythonfmu's library: %s",
                 why ? why : path);
        return;
    }
    /* registered after pythonfmu's library registered its static destructors: runs before them */
    release_python = (void (*)(void))dlsym(library, "finalizePythonInterpreter");
    if (!release_python) return;
    /* kept loaded to the exit, as pythonfmu's library is (module doc): the handler with it */
    if (!dlopen(self.dli_fname, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE)) {
        release_python = NULL;   /* without the handler, pythonfmu's exit as it is */
        return;
    }
    atexit(release_at_exit);
}

__attribute__((destructor)) static void close_library(void) {
    if (library) dlclose(library);   /* its own unload function releases the state first */
    library = NULL;
}

/* pythonfmu's function `name`, or NULL. */
static void *real(const char *name) {
    pthread_once(&library_once, open_library);
    return library ? dlsym(library, name) : NULL;
}

static int category_of(fmi2Status status) {
    switch (status) {
    case fmi2Warning: return LOG_WARNING;
    case fmi2Discard: return LOG_DISCARD;
    case fmi2Error: return LOG_ERROR;
    case fmi2Fatal: return LOG_FATAL;
    default: return LOG_ALL;
    }
}

/* Pass `text` to the host's logger as the native FMU does: as a printf format, '%' doubled. */
static void to_host(const Guard *g, fmi2String name, fmi2Status status, fmi2String category,
                    const char *text) {
    char escaped[2 * MESSAGE_SIZE];
    size_t n = 0;
    const char *p;
    if (!g->host.logger || !g->logging[category_of(status)]) return;
    for (p = text; *p && n + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[n++] = '%';
        escaped[n++] = *p;
    }
    escaped[n] = '\0';
    g->host.logger(g->host.componentEnvironment, name, status,
                   category ? category : CATEGORY_NAMES[category_of(status)], escaped);
}

/* The logger pythonfmu is given: its messages are plain text (it passes no arguments). */
static void guard_logger(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status,
                         fmi2String category, fmi2String message, ...) {
    Guard *g = environment;
    const char *text = message ? message : "";
    if (g->stepping && status >= fmi2Error) {
        strncpy(g->reason, text, sizeof g->reason - 1);
        g->reason[sizeof g->reason - 1] = '\0';
    }
    to_host(g, name, status, category, text);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)real("fmi2Instantiate");
    Guard *g;
    if (!functions) return NULL;
    if (!instantiate) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Fatal,
                              CATEGORY_NAMES[LOG_FATAL], "%s",
                              library_error[0] ? library_error : "no fmi2Instantiate");
        return NULL;
    }
    if (!(g = calloc(1, sizeof *g))) return NULL;
    g->host = *functions;
    g->mine = *functions;
    strncpy(g->name, instanceName ? instanceName : "", sizeof g->name - 1);
    g->mine.logger = guard_logger;
    g->mine.componentEnvironment = g;
    g->logging[LOG_ALL] = loggingOn;
    g->logging[LOG_WARNING] = g->logging[LOG_DISCARD] = g->logging[LOG_ERROR] = 1;
    g->logging[LOG_FATAL] = 1;
    g->component = instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, &g->mine,
                               visible, fmi2True);
    if (!g->component) {
        free(g);
        return NULL;
    }
    pthread_mutex_lock(&lock);
    g->next = guards;
    guards = g;
    pthread_mutex_unlock(&lock);
    return g->component;
}

void fmi2FreeInstance(fmi2Component c) {
    fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)real("fmi2FreeInstance");
    Guard **link, *g = NULL;
    if (!c) return;
    if (free_instance) free_instance(c);   /* it may still log, through its record */
    pthread_mutex_lock(&lock);
    for (link = &guards; *link; link = &(*link)->next)
        if ((*link)->component == c) {
            g = *link;
            *link = g->next;
            break;
        }
    pthread_mutex_unlock(&lock);
    free(g);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Guard *g = find(c);
    size_t k;
    int category;
    if (!g) return fmi2Error;
    if (nCategories == 0) {
        for (category = 0; category < CATEGORIES; category++) g->logging[category] = loggingOn;
        return fmi2OK;
    }
    for (k = 0; k < nCategories; k++) {
        for (category = 0; category < CATEGORIES; category++)
            if (categories[k] && strcmp(categories[k], CATEGORY_NAMES[category]) == 0) break;
        if (category == CATEGORIES) {
            char text[MESSAGE_SIZE];
            strcpy(text, "log category ");
            strncat(text, categories[k] ? categories[k] : "(null)", 256);
            strcat(text, ": must be logAll, logStatusWarning, logStatusDiscard, logStatusError "
                         "or logStatusFatal");
            g->logging[LOG_ERROR] = 1;
            to_host(g, g->name, fmi2Error, CATEGORY_NAMES[LOG_ERROR], text);
            return fmi2Error;
        }
        g->logging[category] = loggingOn;
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)real("fmi2DoStep");
    Guard *g = find(c);
    fmi2Status status;
    if (!g || !do_step) return fmi2Error;
    if (g->ended[0]) {
        to_host(g, g->name, fmi2Error, CATEGORY_NAMES[LOG_ERROR], g->ended);
        return fmi2Error;
    }
    g->reason[0] = '\0';
    g->stepping = 1;
    status = do_step(c, currentCommunicationPoint, communicationStepSize,
                     noSetFMUStatePriorToCurrentPoint);
    g->stepping = 0;
    if (status != fmi2Discard) return status;
    /* the slave refused the step and logged why: the simulation has ended */
    strcpy(g->ended, g->reason[0] ? g->reason : "the step was refused");
    return fmi2Error;
}

fmi2Status fmi2Reset(fmi2Component c) {
    fmi2ResetTYPE *reset = (fmi2ResetTYPE *)real("fmi2Reset");
    Guard *g = find(c);
    if (!g || !reset) return fmi2Error;
    g->ended[0] = '\0';
    return reset(c);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    fmi2GetBooleanStatusTYPE *status = (fmi2GetBooleanStatusTYPE *)real("fmi2GetBooleanStatus");
    Guard *g = find(c);
    if (!g || !status) return fmi2Error;
    if (s != fmi2Terminated) return status(c, s, value);
    *value = g->ended[0] ? fmi2True : fmi2False;
    return fmi2OK;
}

/* Every other function of the FMI 2.0 co-simulation interface, passed on as it is. */
#define FORWARD(name, params, args)                        \
    fmi2Status name params {                               \
        name##TYPE *f = (name##TYPE *)real(#name);         \
        return f ? f args : fmi2Error;                     \
    }

const char *fmi2GetTypesPlatform(void) {
    fmi2GetTypesPlatformTYPE *f = (fmi2GetTypesPlatformTYPE *)real("fmi2GetTypesPlatform");
    return f ? f() : fmi2TypesPlatform;
}

const char *fmi2GetVersion(void) {
    fmi2GetVersionTYPE *f = (fmi2GetVersionTYPE *)real("fmi2GetVersion");
    return f ? f() : fmi2Version;
}

FORWARD(fmi2SetupExperiment, (fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                              fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime),
        (c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime))
FORWARD(fmi2EnterInitializationMode, (fmi2Component c), (c))
FORWARD(fmi2ExitInitializationMode, (fmi2Component c), (c))
FORWARD(fmi2Terminate, (fmi2Component c), (c))
FORWARD(fmi2GetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                      fmi2Real value[]), (c, vr, nvr, value))
FORWARD(fmi2GetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2Integer value[]), (c, vr, nvr, value))
FORWARD(fmi2GetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2Boolean value[]), (c, vr, nvr, value))
FORWARD(fmi2GetString, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                        fmi2String value[]), (c, vr, nvr, value))
FORWARD(fmi2SetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                      const fmi2Real value[]), (c, vr, nvr, value))
FORWARD(fmi2SetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2Integer value[]), (c, vr, nvr, value))
FORWARD(fmi2SetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2Boolean value[]), (c, vr, nvr, value))
FORWARD(fmi2SetString, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                        const fmi2String value[]), (c, vr, nvr, value))
FORWARD(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate *state), (c, state))
FORWARD(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate state), (c, state))
FORWARD(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate *state), (c, state))
FORWARD(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate state, size_t *size),
        (c, state, size))
FORWARD(fmi2SerializeFMUstate, (fmi2Component c, fmi2FMUstate state, fmi2Byte serialized[],
                                size_t size), (c, state, serialized, size))
FORWARD(fmi2DeSerializeFMUstate, (fmi2Component c, const fmi2Byte serialized[], size_t size,
                                  fmi2FMUstate *state), (c, serialized, size, state))
FORWARD(fmi2GetDirectionalDerivative, (fmi2Component c, const fmi2ValueReference unknown[],
                                       size_t nUnknown, const fmi2ValueReference known[],
                                       size_t nKnown, const fmi2Real dvKnown[],
                                       fmi2Real dvUnknown[]),
        (c, unknown, nUnknown, known, nKnown, dvKnown, dvUnknown))
FORWARD(fmi2SetRealInputDerivatives, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Integer order[], const fmi2Real value[]),
        (c, vr, nvr, order, value))
FORWARD(fmi2GetRealOutputDerivatives, (fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[], fmi2Real value[]),
        (c, vr, nvr, order, value))
FORWARD(fmi2CancelStep, (fmi2Component c), (c))
FORWARD(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Status *value), (c, s, value))
FORWARD(fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Real *value),
        (c, s, value))
FORWARD(fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Integer *value),
        (c, s, value))
FORWARD(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind s, fmi2String *value),
        (c, s, value))
