/* The FMI 3.0 co-simulation interface of the native RV reducer FMU.
 *
 * Plumbing only, as fmi2Functions.c: the physics is in model.c, what the two
 * layers share in instance.c (the variables, the inputs check, the state and its
 * bytes), so that this FMU behaves as the FMI 2.0 one: the same outputs, the
 * same refusals with the same log text.  A table that cannot be read is
 * fmi3InstantiateCoSimulation returning NULL after logging why.  A step with an
 * input that is not finite, a step size that is not > 0, a load beyond the
 * emergency-stop class or an input angle that moved faster than the speed limit
 * allows returns fmi3Error with the reason logged and terminateSimulation set,
 * leaves the outputs as they were and ends the simulation: every later step
 * returns fmi3Error with the same reason, until fmi3Reset (no retry could make
 * such an input valid: fmi3Discard would invite one).  Above the momentary maximum
 * class, or above the allowable output speed, the step is computed and a warning
 * logged once per instance.  Initial inputs the model cannot take make
 * fmi3ExitInitializationMode return fmi3Error, the same way.
 *
 * Co-simulation only, without event mode, clocks, early return, intermediate
 * updates or derivatives: the functions of those return fmi3Error and say so
 * (modelDescription.xml declares none of them).
 */
#ifdef __MINGW32__
#define __USE_MINGW_ANSI_STDIO 1   /* C99 printf (two-digit exponents), not msvcrt's */
#endif
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "instance.h"

/* FMI 3.0 wants the independent variable declared: time, after the variables both FMUs have. */
#define TIME VARIABLES

typedef struct {
    char *name;
    fmi3LogMessageCallback logger;
    fmi3InstanceEnvironment environment;
    Core core;
} Instance;

/* -- logging ------------------------------------------------------------------------ */

/* FMI 3.0's logger takes the message as text, not as a printf format: nothing to escape. */
static void log_message(const Instance *instance, fmi3Status status, int category,
                        const char *format, ...) {
    char text[2 * RV_MESSAGE_SIZE];
    va_list args;
    if (!instance->logger || !instance->core.logging[category]) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    instance->logger(instance->environment, status, CATEGORY_NAMES[category], text);
}

#define LOG_ERROR_(instance, ...) log_message(instance, fmi3Error, LOG_ERROR, __VA_ARGS__)

/* The warnings of the last step or initialisation (a load, a speed), at status fmi3Warning. */
static void log_warnings(Instance *instance) {
    const char *warning;
    while ((warning = core_next_warning(&instance->core)) != NULL)
        log_message(instance, fmi3Warning, LOG_WARNING, "%s", warning);
}

/* The table's path: FMI 3.0 gives the resources folder as a native path ending in a separator
 * (one is added where a host leaves it out).  0 on success. */
static int table_path(const char *resources, char *path, size_t size) {
    size_t n;
    if (!resources || !*resources) return -1;
    n = strlen(resources);
    if (resources[n - 1] == '/' || resources[n - 1] == '\\')
        return snprintf(path, size, "%s%s", resources, TABLE_NAME) < (int)size ? 0 : -1;
    return snprintf(path, size, "%s/%s", resources, TABLE_NAME) < (int)size ? 0 : -1;
}

/* -- life cycle ----------------------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    char path[4096], message[RV_MESSAGE_SIZE];
    Instance *instance;
    /* the binary is the same for every reducer: the table carries the data */
    (void)instantiationToken, (void)visible, (void)requiredIntermediateVariables,
        (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    (void)earlyReturnAllowed;   /* allowed, never taken: every step completes */
    instance = calloc(1, sizeof *instance);
    if (!instance) return NULL;
    instance->name = malloc(strlen(instanceName ? instanceName : "") + 1);
    if (!instance->name) {
        free(instance);
        return NULL;
    }
    strcpy(instance->name, instanceName ? instanceName : "");
    instance->logger = logMessage;
    instance->environment = instanceEnvironment;
    instance->core.logging[LOG_EVENTS] = loggingOn;
    instance->core.logging[LOG_WARNING] = instance->core.logging[LOG_ERROR] = 1;
    core_reset(&instance->core);

    if (eventModeUsed) {
        LOG_ERROR_(instance, "eventModeUsed: this FMU has no event mode (hasEventMode is false)");
    } else if (table_path(resourcePath, path, sizeof path) != 0) {
        LOG_ERROR_(instance, "resourcePath = %s: must be the path of the FMU's resources folder",
                   resourcePath ? resourcePath : "(null)");
    } else if (te_map_read(path, &instance->core.map, message, sizeof message) != 0) {
        LOG_ERROR_(instance, "%s", message);
    } else {
        log_message(instance, fmi3OK, LOG_EVENTS, "TE map %s: %d angle points x %d torque levels, "
                    "ratio %g, rated torque %g N*m", path, instance->core.map.points,
                    instance->core.map.levels, instance->core.map.ratio,
                    instance->core.map.rated_torque);
        return instance;
    }
    free(instance->name);
    free(instance);
    return NULL;
}

/* Only co-simulation: the other interface types are refused through their own logger. */
static fmi3Instance co_simulation_only(fmi3InstanceEnvironment environment,
                                       fmi3LogMessageCallback logMessage) {
    if (logMessage)
        logMessage(environment, fmi3Error, CATEGORY_NAMES[LOG_ERROR],
                   "this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible,
        (void)loggingOn;
    return co_simulation_only(instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible,
        (void)loggingOn, (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    return co_simulation_only(instanceEnvironment, logMessage);
}

void fmi3FreeInstance(fmi3Instance c) {
    Instance *instance = c;
    if (!instance) return;
    te_map_free(&instance->core.map);
    free(instance->name);
    free(instance);
}

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    Instance *instance = c;
    long unknown;
    if (!instance) return fmi3Error;
    unknown = core_set_logging(&instance->core, loggingOn, nCategories, categories);
    if (unknown < 0) return fmi3OK;
    LOG_ERROR_(instance, "log category %s: must be logEvents, logStatusWarning or logStatusError",
               categories[unknown] ? categories[unknown] : "(null)");
    return fmi3Error;
}

static fmi3Status in_mode(Instance *instance, Mode mode, const char *function) {
    if (!instance) return fmi3Error;
    if (instance->core.state.mode == mode) return fmi3OK;
    LOG_ERROR_(instance, "%s called in the wrong state of the instance", function);
    return fmi3Error;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *instance = c;
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    if (in_mode(instance, INSTANTIATED, "fmi3EnterInitializationMode") != fmi3OK) return fmi3Error;
    instance->core.state.reducer.time = startTime;
    instance->core.state.mode = INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Instance *instance = c;
    InputCheck check;
    if (in_mode(instance, INITIALIZATION, "fmi3ExitInitializationMode") != fmi3OK) return fmi3Error;
    check = core_exit_initialization(&instance->core);
    log_warnings(instance);
    if (check != INPUT_REFUSED) return fmi3OK;
    LOG_ERROR_(instance, "%s", instance->core.failed);
    return fmi3Error;   /* as the FMI 2.0 FMU: and every later step, with the same reason */
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    Instance *instance = c;
    if (in_mode(instance, STEPPING, "fmi3Terminate") != fmi3OK) return fmi3Error;
    instance->core.state.mode = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    Instance *instance = c;
    if (!instance) return fmi3Error;
    core_reset(&instance->core);
    log_message(instance, fmi3OK, LOG_EVENTS, "reset to the start values");
    return fmi3OK;
}

/* -- variables ------------------------------------------------------------------------ */

/* Every variable is a scalar: as many values as value references. */
static fmi3Status scalars(Instance *instance, size_t nValueReferences, size_t nValues,
                          const char *function) {
    if (nValues == nValueReferences) return fmi3OK;
    LOG_ERROR_(instance, "%s: %lu values for %lu value references of scalar variables", function,
               (unsigned long)nValues, (unsigned long)nValueReferences);
    return fmi3Error;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    Instance *instance = c;
    size_t k;
    if (!instance) return fmi3Error;
    if (scalars(instance, nValueReferences, nValues, "fmi3GetFloat64") != fmi3OK) return fmi3Error;
    core_update_initial_unknowns(&instance->core);
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == TIME) {
            values[k] = instance->core.state.reducer.time;
            continue;
        }
        if (core_get(&instance->core, valueReferences[k], &values[k]) != 0) {
            LOG_ERROR_(instance, "fmi3GetFloat64: no Float64 variable has value reference %u",
                       (unsigned)valueReferences[k]);
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    Instance *instance = c;
    size_t k;
    int set;
    if (!instance) return fmi3Error;
    if (scalars(instance, nValueReferences, nValues, "fmi3SetFloat64") != fmi3OK) return fmi3Error;
    for (k = 0; k < nValueReferences; k++) {
        set = core_set(&instance->core, valueReferences[k], values[k]);
        if (set != 0) {
            LOG_ERROR_(instance, "fmi3SetFloat64: value reference %u %s",
                       (unsigned)valueReferences[k],
                       set == 2 ? "is the fixed parameter temperature_C: it can be set only "
                                  "before initialisation ends"
                       : set > 0 ? "is an output: it cannot be set"
                       : valueReferences[k] == TIME ? "is time: it cannot be set"
                                                    : "is not a Float64 variable");
            return fmi3Error;
        }
    }
    return fmi3OK;
}

/* This FMU has Float64 variables only: a call for another type must name none. */
static fmi3Status no_variables(Instance *instance, size_t nValueReferences, const char *function) {
    if (!instance) return fmi3Error;
    if (nValueReferences == 0) return fmi3OK;
    LOG_ERROR_(instance, "%s: this FMU has no variables of that type", function);
    return fmi3Error;
}

/* The getters and setters of the types this FMU has no variables of. */
#define NO_GETTER(type, name)                                                                 \
    fmi3Status name(fmi3Instance c, const fmi3ValueReference valueReferences[],              \
                    size_t nValueReferences, type values[], size_t nValues) {                \
        (void)valueReferences, (void)values, (void)nValues;                                   \
        return no_variables(c, nValueReferences, #name);                                      \
    }
#define NO_SETTER(type, name)                                                                 \
    fmi3Status name(fmi3Instance c, const fmi3ValueReference valueReferences[],              \
                    size_t nValueReferences, const type values[], size_t nValues) {          \
        (void)valueReferences, (void)values, (void)nValues;                                   \
        return no_variables(c, nValueReferences, #name);                                      \
    }

NO_GETTER(fmi3Float32, fmi3GetFloat32)
NO_GETTER(fmi3Int8, fmi3GetInt8)
NO_GETTER(fmi3UInt8, fmi3GetUInt8)
NO_GETTER(fmi3Int16, fmi3GetInt16)
NO_GETTER(fmi3UInt16, fmi3GetUInt16)
NO_GETTER(fmi3Int32, fmi3GetInt32)
NO_GETTER(fmi3UInt32, fmi3GetUInt32)
NO_GETTER(fmi3Int64, fmi3GetInt64)
NO_GETTER(fmi3UInt64, fmi3GetUInt64)
NO_GETTER(fmi3Boolean, fmi3GetBoolean)
NO_GETTER(fmi3String, fmi3GetString)
NO_SETTER(fmi3Float32, fmi3SetFloat32)
NO_SETTER(fmi3Int8, fmi3SetInt8)
NO_SETTER(fmi3UInt8, fmi3SetUInt8)
NO_SETTER(fmi3Int16, fmi3SetInt16)
NO_SETTER(fmi3UInt16, fmi3SetUInt16)
NO_SETTER(fmi3Int32, fmi3SetInt32)
NO_SETTER(fmi3UInt32, fmi3SetUInt32)
NO_SETTER(fmi3Int64, fmi3SetInt64)
NO_SETTER(fmi3UInt64, fmi3SetUInt64)
NO_SETTER(fmi3Boolean, fmi3SetBoolean)
NO_SETTER(fmi3String, fmi3SetString)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues) {
    (void)valueReferences, (void)valueSizes, (void)values, (void)nValues;
    return no_variables(c, nValueReferences, "fmi3GetBinary");
}

fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueReferences, (void)valueSizes, (void)values, (void)nValues;
    return no_variables(c, nValueReferences, "fmi3SetBinary");
}

fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    (void)valueReferences, (void)values;
    return no_variables(c, nValueReferences, "fmi3GetClock");
}

fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    (void)valueReferences, (void)values;
    return no_variables(c, nValueReferences, "fmi3SetClock");
}

/* -- FMU states ----------------------------------------------------------------------- */

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *FMUState) {
    Instance *instance = c;
    if (!instance || !FMUState) return fmi3Error;
    if (!(*FMUState = core_copy_state(&instance->core.state, *FMUState))) {
        LOG_ERROR_(instance, "fmi3GetFMUState: out of memory");
        return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState FMUState) {
    Instance *instance = c;
    if (!instance || !FMUState) return fmi3Error;
    core_copy_state(FMUState, &instance->core.state);
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *FMUState) {
    if (!c || !FMUState) return fmi3Error;
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState FMUState, size_t *size) {
    (void)FMUState;
    if (!c || !size) return fmi3Error;
    *size = core_serialized_size();
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    Instance *instance = c;
    if (!instance || !FMUState) return fmi3Error;
    if (size < core_serialized_size()) {
        LOG_ERROR_(instance, "fmi3SerializeFMUState: %lu bytes given, %lu needed",
                   (unsigned long)size, (unsigned long)core_serialized_size());
        return fmi3Error;
    }
    core_serialize(FMUState, serializedState);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    Instance *instance = c;
    State state;
    if (!instance || !FMUState) return fmi3Error;
    if (core_deserialize(serializedState, size, &state) != 0) {
        LOG_ERROR_(instance, "fmi3DeserializeFMUState: %lu bytes that are not a state of this FMU",
                   (unsigned long)size);
        return fmi3Error;
    }
    if (!(*FMUState = core_copy_state(&state, *FMUState))) {
        LOG_ERROR_(instance, "fmi3DeserializeFMUState: out of memory");
        return fmi3Error;
    }
    return fmi3OK;
}

/* -- stepping ------------------------------------------------------------------------- */

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Instance *instance = c;
    InputCheck check;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (in_mode(instance, STEPPING, "fmi3DoStep") != fmi3OK) return fmi3Error;
    check = core_step(&instance->core, currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    /* a refused input, at initialisation or in a step, ends the simulation */
    if (terminateSimulation)
        *terminateSimulation = core_terminated(&instance->core) ? fmi3True : fmi3False;
    if (lastSuccessfulTime)
        *lastSuccessfulTime = check == INPUT_REFUSED ? currentCommunicationPoint
                                                     : instance->core.state.reducer.time;
    log_warnings(instance);
    if (check != INPUT_REFUSED) return fmi3OK;
    LOG_ERROR_(instance, "%s", instance->core.failed);
    return fmi3Error;   /* not fmi3Discard: no retry can make the input valid */
}

/* -- not provided (modelDescription.xml declares none of these capabilities) ---------- */

static fmi3Status not_provided(fmi3Instance c, const char *function) {
    Instance *instance = c;
    if (!instance) return fmi3Error;
    LOG_ERROR_(instance, "%s is not provided by this FMU", function);
    return fmi3Error;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) { return not_provided(c, "fmi3EnterEventMode"); }

fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    return not_provided(c, "fmi3EnterStepMode (no event mode: step mode follows initialisation)");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    return not_provided(c, "fmi3EnterConfigurationMode");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    return not_provided(c, "fmi3ExitConfigurationMode");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
    return not_provided(c, "fmi3EvaluateDiscreteStates");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate, (void)terminateSimulation,
        (void)nominalsOfContinuousStatesChanged, (void)valuesOfContinuousStatesChanged,
        (void)nextEventTimeDefined, (void)nextEventTime;
    return not_provided(c, "fmi3UpdateDiscreteStates");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference, (void)nDependencies;
    return not_provided(c, "fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
    (void)dependent, (void)elementIndicesOfDependent, (void)independents,
        (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies;
    return not_provided(c, "fmi3GetVariableDependencies");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                        size_t nUnknowns, const fmi3ValueReference knowns[],
                                        size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed,
        (void)sensitivity, (void)nSensitivity;
    return not_provided(c, "fmi3GetDirectionalDerivative");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                    size_t nUnknowns, const fmi3ValueReference knowns[],
                                    size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                    fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed,
        (void)sensitivity, (void)nSensitivity;
    return not_provided(c, "fmi3GetAdjointDerivative");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues) {
    (void)valueReferences, (void)nValueReferences, (void)orders, (void)values, (void)nValues;
    return not_provided(c, "fmi3GetOutputDerivatives");
}

/* Clocks: this FMU has none. */
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences, (void)intervals, (void)qualifiers;
    return no_variables(c, nValueReferences, "fmi3GetIntervalDecimal");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences, (void)counters, (void)resolutions, (void)qualifiers;
    return no_variables(c, nValueReferences, "fmi3GetIntervalFraction");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences, (void)shifts;
    return no_variables(c, nValueReferences, "fmi3GetShiftDecimal");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)counters, (void)resolutions;
    return no_variables(c, nValueReferences, "fmi3GetShiftFraction");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences, (void)intervals;
    return no_variables(c, nValueReferences, "fmi3SetIntervalDecimal");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)counters, (void)resolutions;
    return no_variables(c, nValueReferences, "fmi3SetIntervalFraction");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    (void)valueReferences, (void)shifts;
    return no_variables(c, nValueReferences, "fmi3SetShiftDecimal");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)counters, (void)resolutions;
    return no_variables(c, nValueReferences, "fmi3SetShiftFraction");
}

/* -- model exchange and scheduled execution: exported because importers (fmpy among them) look
 * up every function of the API; no instance of those types is ever made ---------------- */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    return not_provided(c, "fmi3EnterContinuousTimeMode");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    return not_provided(c, "fmi3CompletedIntegratorStep");
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    (void)time;
    return not_provided(c, "fmi3SetTime");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    return not_provided(c, "fmi3SetContinuousStates");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives, (void)nContinuousStates;
    return not_provided(c, "fmi3GetContinuousStateDerivatives");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    (void)eventIndicators, (void)nEventIndicators;
    return not_provided(c, "fmi3GetEventIndicators");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    return not_provided(c, "fmi3GetContinuousStates");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals, (void)nContinuousStates;
    return not_provided(c, "fmi3GetNominalsOfContinuousStates");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *nEventIndicators) {
    (void)nEventIndicators;
    return not_provided(c, "fmi3GetNumberOfEventIndicators");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *nContinuousStates) {
    (void)nContinuousStates;
    return not_provided(c, "fmi3GetNumberOfContinuousStates");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference, (void)activationTime;
    return not_provided(c, "fmi3ActivateModelPartition");
}
