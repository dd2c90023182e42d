/* The FMI 2.0 co-simulation interface of the native RV reducer FMU.
 *
 * Plumbing only: the physics is in model.c, what this layer shares with the
 * FMI 3.0 one (fmi3Functions.c) in instance.c: the variables, the inputs check,
 * the state and its bytes.
 *
 * Behaviour (docs/model.md section 8): nothing here aborts or hangs the host.  A
 * table that cannot be read is fmi2Instantiate returning NULL after logging why.
 * A step with an input that is not finite, a step size that is not > 0, a load
 * beyond the emergency-stop class or an input angle that moved faster than the
 * speed limit allows returns fmi2Error with the reason logged, leaves the outputs
 * as they were and ends the simulation: every later step returns fmi2Error with
 * the same reason and fmi2GetBooleanStatus(fmi2Terminated) says true, until
 * fmi2Reset.  Not fmi2Discard: no retry of the step can make such an input valid,
 * and fmpy (0.3.32, simulation.py) retries a discarded step for ever unless
 * fmi2Terminated is true, and then ends without raising (the host would not learn
 * of it); on fmi2Error fmpy and libcosim stop with an error.  Above the momentary
 * maximum class, or above the allowable output speed, the step is computed and a
 * warning logged once per instance.  Initial inputs the model cannot take make
 * fmi2ExitInitializationMode return fmi2Error, the same way.
 *
 * Logging: errors and warnings always reach the host's logger (it must learn why
 * a step was refused), unless the host switches their category off with
 * fmi2SetDebugLogging; the informational messages (category logEvents) only
 * when debug logging is on.
 */
#ifdef __MINGW32__
#define __USE_MINGW_ANSI_STDIO 1   /* C99 printf (two-digit exponents), not msvcrt's */
#endif
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "instance.h"

typedef struct {
    char *name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment environment;
    Core core;
} Instance;

/* -- logging ------------------------------------------------------------------------ */

static void log_message(const Instance *instance, fmi2Status status, int category,
                        const char *format, ...) {
    char text[2 * RV_MESSAGE_SIZE], escaped[4 * RV_MESSAGE_SIZE];
    size_t n = 0;
    const char *p;
    va_list args;
    if (!instance->logger || !instance->core.logging[category]) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    /* the logger takes a printf format: a '%' of a path or a name must reach it as "%%" */
    for (p = text; *p && n + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[n++] = '%';
        escaped[n++] = *p;
    }
    escaped[n] = '\0';
    instance->logger(instance->environment, instance->name, status, CATEGORY_NAMES[category],
                     escaped);
}

#define LOG_ERROR_(instance, ...) log_message(instance, fmi2Error, LOG_ERROR, __VA_ARGS__)

/* The warnings of the last step or initialisation (a load, a speed), at status fmi2Warning. */
static void log_warnings(Instance *instance) {
    const char *warning;
    while ((warning = core_next_warning(&instance->core)) != NULL)
        log_message(instance, fmi2Warning, LOG_WARNING, "%s", warning);
}

/* -- the resource location ------------------------------------------------------------ */

static int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* The path of the table from the resources' file URI: file:///dir, file:/dir or
 * file://localhost/dir (file:///C:/dir on Windows), percent-encoded.  0 on success. */
static int table_path(const char *uri, char *path, size_t size) {
    const char *p;
    size_t n = 0;
    if (!uri || strncmp(uri, "file:", 5) != 0) return -1;
    p = uri + 5;
    if (strncmp(p, "//", 2) == 0) {   /* an authority: empty or localhost */
        p += 2;
        if (strncmp(p, "localhost", 9) == 0) p += 9;
        if (*p != '/') return -1;
    }
    if (*p != '/') return -1;
#ifdef _WIN32
    if (((p[1] >= 'A' && p[1] <= 'Z') || (p[1] >= 'a' && p[1] <= 'z')) && p[2] == ':') p++;
#endif
    for (; *p; p++) {
        char c = *p;
        if (c == '%') {
            int high = hex_value(p[1]), low = high < 0 ? -1 : hex_value(p[2]);
            if (low < 0) return -1;
            c = (char)(high * 16 + low);
            p += 2;
        }
        if (n + 1 >= size) return -1;
        path[n++] = c;
    }
    if (n > 0 && path[n - 1] == '/') n--;
    if (n + 1 + strlen(TABLE_NAME) + 1 > size) return -1;
    path[n++] = '/';
    strcpy(path + n, TABLE_NAME);
    return 0;
}

/* -- life cycle ----------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    char path[4096], message[RV_MESSAGE_SIZE];
    Instance *instance;
    (void)fmuGUID;   /* the binary is the same for every reducer: the table carries the data */
    (void)visible;
    if (!functions) return NULL;
    instance = calloc(1, sizeof *instance);
    if (!instance) return NULL;
    instance->name = malloc(strlen(instanceName ? instanceName : "") + 1);
    if (!instance->name) {
        free(instance);
        return NULL;
    }
    strcpy(instance->name, instanceName ? instanceName : "");
    instance->logger = functions->logger;
    instance->environment = functions->componentEnvironment;
    instance->core.logging[LOG_EVENTS] = loggingOn;
    instance->core.logging[LOG_WARNING] = instance->core.logging[LOG_ERROR] = 1;
    core_reset(&instance->core);

    if (fmuType != fmi2CoSimulation) {
        LOG_ERROR_(instance, "this FMU supports co-simulation only");
    } else if (table_path(fmuResourceLocation, path, sizeof path) != 0) {
        LOG_ERROR_(instance, "fmuResourceLocation = %s: must be a file URI of the FMU's resources "
                   "folder", fmuResourceLocation ? fmuResourceLocation : "(null)");
    } else if (te_map_read(path, &instance->core.map, message, sizeof message) != 0) {
        LOG_ERROR_(instance, "%s", message);
    } else {
        log_message(instance, fmi2OK, LOG_EVENTS, "TE map %s: %d angle points x %d torque levels, "
                    "ratio %g, rated torque %g N*m", path, instance->core.map.points,
                    instance->core.map.levels, instance->core.map.ratio, instance->core.map.rated_torque);
        return instance;
    }
    free(instance->name);
    free(instance);
    return NULL;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *instance = c;
    if (!instance) return;
    te_map_free(&instance->core.map);
    free(instance->name);
    free(instance);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *instance = c;
    long unknown;
    if (!instance) return fmi2Error;
    unknown = core_set_logging(&instance->core, loggingOn, nCategories, categories);
    if (unknown < 0) return fmi2OK;
    LOG_ERROR_(instance, "log category %s: must be logEvents, logStatusWarning or logStatusError",
               categories[unknown] ? categories[unknown] : "(null)");
    return fmi2Error;
}

static fmi2Status in_mode(Instance *instance, Mode mode, const char *function) {
    if (!instance) return fmi2Error;
    if (instance->core.state.mode == mode) return fmi2OK;
    LOG_ERROR_(instance, "%s called in the wrong state of the instance", function);
    return fmi2Error;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *instance = c;
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    if (in_mode(instance, INSTANTIATED, "fmi2SetupExperiment") != fmi2OK) return fmi2Error;
    instance->core.state.reducer.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *instance = c;
    if (in_mode(instance, INSTANTIATED, "fmi2EnterInitializationMode") != fmi2OK) return fmi2Error;
    instance->core.state.mode = INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *instance = c;
    InputCheck check;
    if (in_mode(instance, INITIALIZATION, "fmi2ExitInitializationMode") != fmi2OK) return fmi2Error;
    check = core_exit_initialization(&instance->core);
    log_warnings(instance);
    if (check != INPUT_REFUSED) return fmi2OK;
    LOG_ERROR_(instance, "%s", instance->core.failed);
    return fmi2Error;   /* and every later step, with the same reason */
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *instance = c;
    if (in_mode(instance, STEPPING, "fmi2Terminate") != fmi2OK) return fmi2Error;
    instance->core.state.mode = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *instance = c;
    if (!instance) return fmi2Error;
    core_reset(&instance->core);
    log_message(instance, fmi2OK, LOG_EVENTS, "reset to the start values");
    return fmi2OK;
}

/* -- variables ------------------------------------------------------------------------ */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    Instance *instance = c;
    size_t k;
    if (!instance) return fmi2Error;
    core_update_initial_unknowns(&instance->core);
    for (k = 0; k < nvr; k++) {
        if (core_get(&instance->core, vr[k], &value[k]) != 0) {
            LOG_ERROR_(instance, "fmi2GetReal: no Real variable has value reference %u",
                       (unsigned)vr[k]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    Instance *instance = c;
    size_t k;
    int set;
    if (!instance) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        set = core_set(&instance->core, vr[k], value[k]);
        if (set != 0) {
            LOG_ERROR_(instance, "fmi2SetReal: value reference %u %s", (unsigned)vr[k],
                       set == 2 ? "is the fixed parameter temperature_C: it can be set only "
                                  "before initialisation ends"
                       : set > 0 ? "is an output: it cannot be set" : "is not a Real variable");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

/* This FMU has Real variables only. */
static fmi2Status no_variables(Instance *instance, size_t nvr, const char *function) {
    if (!instance) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    LOG_ERROR_(instance, "%s: this FMU has no variables of that type", function);
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    (void)vr, (void)value;
    return no_variables(c, nvr, "fmi2GetInteger");
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    (void)vr, (void)value;
    return no_variables(c, nvr, "fmi2GetBoolean");
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)vr, (void)value;
    return no_variables(c, nvr, "fmi2GetString");
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    (void)vr, (void)value;
    return no_variables(c, nvr, "fmi2SetInteger");
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    (void)vr, (void)value;
    return no_variables(c, nvr, "fmi2SetBoolean");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)vr, (void)value;
    return no_variables(c, nvr, "fmi2SetString");
}

/* -- FMU states ----------------------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *instance = c;
    if (!instance || !FMUstate) return fmi2Error;
    if (!(*FMUstate = core_copy_state(&instance->core.state, *FMUstate))) {
        LOG_ERROR_(instance, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Instance *instance = c;
    if (!instance || !FMUstate) return fmi2Error;
    core_copy_state(FMUstate, &instance->core.state);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    if (!c || !FMUstate) return fmi2Error;
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate;
    if (!c || !size) return fmi2Error;
    *size = core_serialized_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    Instance *instance = c;
    if (!instance || !FMUstate) return fmi2Error;
    if (size < core_serialized_size()) {
        LOG_ERROR_(instance, "fmi2SerializeFMUstate: %lu bytes given, %lu needed",
                   (unsigned long)size, (unsigned long)core_serialized_size());
        return fmi2Error;
    }
    core_serialize(FMUstate, (unsigned char *)serializedState);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    Instance *instance = c;
    State state;
    if (!instance || !FMUstate) return fmi2Error;
    if (core_deserialize((const unsigned char *)serializedState, size, &state) != 0) {
        LOG_ERROR_(instance, "fmi2DeSerializeFMUstate: %lu bytes that are not a state of this FMU",
                   (unsigned long)size);
        return fmi2Error;
    }
    if (!(*FMUstate = core_copy_state(&state, *FMUstate))) {
        LOG_ERROR_(instance, "fmi2DeSerializeFMUstate: out of memory");
        return fmi2Error;
    }
    return fmi2OK;
}

/* -- stepping ------------------------------------------------------------------------- */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *instance = c;
    InputCheck check;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (in_mode(instance, STEPPING, "fmi2DoStep") != fmi2OK) return fmi2Error;
    check = core_step(&instance->core, currentCommunicationPoint, communicationStepSize);
    log_warnings(instance);
    if (check != INPUT_REFUSED) return fmi2OK;
    LOG_ERROR_(instance, "%s", instance->core.failed);
    return fmi2Error;   /* the simulation has ended (core_step): not a step to retry */
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Instance *instance = c;
    if (!instance) return fmi2Error;
    LOG_ERROR_(instance, "fmi2CancelStep: every step completes at once (no asynchronous steps)");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    Instance *instance = c;
    if (!instance) return fmi2Error;
    if (s == fmi2DoStepStatus) {
        *value = fmi2OK;   /* steps are never pending */
        return fmi2OK;
    }
    LOG_ERROR_(instance, "fmi2GetStatus: status kind %d not provided", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *instance = c;
    if (!instance) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = instance->core.state.reducer.time;
        return fmi2OK;
    }
    LOG_ERROR_(instance, "fmi2GetRealStatus: status kind %d not provided", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    Instance *instance = c;
    (void)value;
    if (!instance) return fmi2Error;
    LOG_ERROR_(instance, "fmi2GetIntegerStatus: status kind %d not provided", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *instance = c;
    if (!instance) return fmi2Error;
    if (s == fmi2Terminated) {
        /* a refused input, at initialisation or in a step, ends the simulation */
        *value = core_terminated(&instance->core) ? fmi2True : fmi2False;
        return fmi2OK;
    }
    LOG_ERROR_(instance, "fmi2GetBooleanStatus: status kind %d not provided", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    Instance *instance = c;
    (void)value;
    if (!instance) return fmi2Error;
    LOG_ERROR_(instance, "fmi2GetStringStatus: status kind %d not provided", (int)s);
    return fmi2Discard;
}

/* -- not provided (the capability flags of modelDescription.xml say so) ---------------- */

static fmi2Status not_provided(fmi2Component c, const char *function) {
    Instance *instance = c;
    if (!instance) return fmi2Error;
    LOG_ERROR_(instance, "%s is not provided by this FMU", function);
    return fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown,
        (void)dvUnknown;
    return not_provided(c, "fmi2GetDirectionalDerivative");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return not_provided(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return not_provided(c, "fmi2GetRealOutputDerivatives");
}
