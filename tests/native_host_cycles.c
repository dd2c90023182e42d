/* A plain C FMI 2.0 host that puts the native reducer FMU through its whole life cycle,
 * over and over, for a memory checker (tests/test_fmu_native_hosts.py runs it under
 * valgrind and, built with -fsanitize=address,undefined, with the FMU built the same way).
 *
 * Usage: native_host_cycles LIBRARY RESOURCES_URI BAD_RESOURCES_URI GUID CYCLES STEPS
 *
 * Each cycle (`one_cycle`): fmi2Instantiate, fmi2SetDebugLogging (an unknown category too),
 * setup, initial inputs, the initial unknowns in initialisation mode, exit; STEPS steps of
 * 1 ms with inputs that take every warning path of fmi2DoStep (a load beyond the momentary
 * class, an input speed above the allowable one); the FMU state got, serialised, read back,
 * set and freed, with a re-step that must repeat the step taken from it; the status functions
 * and the calls the FMU refuses; fmi2Terminate, fmi2Reset and a second start that must repeat
 * the first outputs; then (`refusals`) from a fresh start each input no retry can make valid
 * (a NaN, an infinite load, a zero step size, a load beyond the emergency-stop class, an input
 * speed beyond the limit) and bad initial inputs: each must end the simulation with fmi2Error
 * and fmi2Terminated, the outputs unchanged, every later step refused; fmi2FreeInstance.
 * Every cycle must give the same outputs, to the bit.  Then (`refused_instances`)
 * fmi2Instantiate on BAD_RESOURCES_URI (a corrupted table), on a URI that is not a file URI
 * and for model exchange: each must return NULL.
 *
 * Prints one line of counts and the last TE; exits 0 when every FMI call returned what it
 * should.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "host_checks.h"

enum { THETA_IN, TAU_LOAD, THETA_OUT, OMEGA_OUT, TE, TE_ARCSEC, TAU_IN };   /* value references */

static const fmi2ValueReference IN[2] = {THETA_IN, TAU_LOAD};
static const fmi2ValueReference OUT[5] = {THETA_OUT, OMEGA_OUT, TE, TE_ARCSEC, TAU_IN};
enum { OUT_TE = 2 };   /* te in OUT */

static int messages[fmi2Pending + 1];   /* log messages by status */
static int echo = 1;                    /* print them (the first cycle, the refused instances) */
static int refused = 0;                 /* steps refused (fmi2Error), over all cycles */

/* fmi2CallbackLogger: counts the messages by status, prints them while `echo` is set. */
static void log_message(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                        fmi2String category, fmi2String message, ...) {
    char text[8192];
    va_list args;
    (void)env;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    if (status >= fmi2OK && status <= fmi2Pending) messages[status]++;
    if (echo) fprintf(stderr, "[%s] %s: %s\n", category, name, text);
}

static fmi2CallbackFunctions callbacks = {log_message, calloc, free, NULL, NULL};

#define FUNCTIONS(X)                                                                              \
    X(GetVersion) X(GetTypesPlatform) X(Instantiate) X(SetDebugLogging) X(SetupExperiment)        \
    X(EnterInitializationMode) X(ExitInitializationMode) X(SetReal) X(GetReal) X(DoStep)          \
    X(GetFMUstate) X(SetFMUstate) X(FreeFMUstate) X(SerializedFMUstateSize) X(SerializeFMUstate)  \
    X(DeSerializeFMUstate) X(GetRealStatus) X(GetBooleanStatus) X(GetStatus) X(GetInteger)        \
    X(GetDirectionalDerivative) X(CancelStep) X(Terminate) X(Reset) X(FreeInstance)

#define MEMBER(f) fmi2##f##TYPE *f;
typedef struct { FUNCTIONS(MEMBER) } Fmi;

static int load(void *lib, Fmi *fmi) {
#define LOAD(f)                                                                                   \
    if (!(fmi->f = (fmi2##f##TYPE *)dlsym(lib, "fmi2" #f))) {                                     \
        fprintf(stderr, "fmi2%s is not exported\n", #f);                                          \
        return 10;                                                                                \
    }
    FUNCTIONS(LOAD)
    return 0;
}

/* Roll back to `state` (taken after the step before) through its serialised bytes, re-take
 * the step with inputs `u` at time t: its outputs must be `value`. */
static int roll_back_and_re_step(const Fmi *fmi, fmi2Component c, fmi2FMUstate *state,
                                 const fmi2Real u[2], fmi2Real t, const fmi2Real value[5]) {
    fmi2FMUstate restored = NULL;
    fmi2Real again[5];
    fmi2Byte *bytes;
    size_t size = 0;
    EXPECT(fmi->SerializedFMUstateSize(c, *state, &size), fmi2OK);
    CHECK((bytes = malloc(size)) != NULL);
    EXPECT(fmi->SerializeFMUstate(c, *state, bytes, size - 1), fmi2Error);   /* too small */
    EXPECT(fmi->SerializeFMUstate(c, *state, bytes, size), fmi2OK);
    EXPECT(fmi->DeSerializeFMUstate(c, bytes, size - 1, &restored), fmi2Error);
    EXPECT(fmi->DeSerializeFMUstate(c, bytes, size, &restored), fmi2OK);
    free(bytes);
    EXPECT(fmi->SetFMUstate(c, restored), fmi2OK);
    EXPECT(fmi->SetReal(c, IN, 2, u), fmi2OK);
    EXPECT(fmi->DoStep(c, t, 1e-3, fmi2False), fmi2OK);
    EXPECT(fmi->GetReal(c, OUT, 5, again), fmi2OK);
    CHECK(memcmp(again, value, sizeof again) == 0);
    EXPECT(fmi->FreeFMUstate(c, &restored), fmi2OK);
    EXPECT(fmi->FreeFMUstate(c, state), fmi2OK);
    CHECK(*state == NULL && restored == NULL);
    return 0;
}

/* STEPS steps of 1 ms; the outputs of the last in `last`, the sum of the TE in `sum`. */
static int steps_with_every_path(const Fmi *fmi, fmi2Component c, int steps, fmi2Real last[5],
                                 fmi2Real *sum) {
    fmi2FMUstate state = NULL;
    fmi2Real t = 0.0, value[5];
    int k, failed;
    *sum = 0.0;
    for (k = 0; k < steps; k++, t += 1e-3) {
        fmi2Real u[2] = {0.37 * k - 20.0, 300.0 * (k % 7 - 3)};   /* both branches */
        if (k == steps / 2) u[1] = -1300.0;                   /* > momentary: warns */
        if (k == steps / 2 + 1) u[0] += 1.2;                  /* 124 rpm out > 70: warns */
        EXPECT(fmi->SetReal(c, IN, 2, u), fmi2OK);
        EXPECT(fmi->DoStep(c, t, 1e-3, fmi2True), fmi2OK);
        EXPECT(fmi->GetReal(c, OUT, 5, value), fmi2OK);
        *sum += value[OUT_TE];
        if (k == steps / 4) {
            EXPECT(fmi->GetFMUstate(c, &state), fmi2OK);
            EXPECT(fmi->GetFMUstate(c, &state), fmi2OK);   /* the same state, overwritten */
        } else if (state && (failed = roll_back_and_re_step(fmi, c, &state, u, t, value))) {
            return failed;
        }
    }
    memcpy(last, value, sizeof value);
    return 0;
}

/* From a fresh start, one good step and then each input no retry can make valid: fmi2Error,
 * the outputs unchanged, fmi2Terminated, and the next step (good inputs) refused too; then bad
 * initial inputs: fmi2ExitInitializationMode and every step after it refused. */
static int refusals(const Fmi *fmi, fmi2Component c) {
    const fmi2Real start[2] = {-20.0, -50.0};
    fmi2Real before[5], after[5], time, bad_start[2] = {NAN, -50.0};
    fmi2Boolean terminated;
    int kind;
    for (kind = 0; kind < 5; kind++) {
        fmi2Real u[2] = {-19.63, -100.0}, h = 1e-3;
        EXPECT(fmi->Reset(c), fmi2OK);
        EXPECT(fmi->SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
        EXPECT(fmi->SetReal(c, IN, 2, start), fmi2OK);
        EXPECT(fmi->EnterInitializationMode(c), fmi2OK);
        EXPECT(fmi->ExitInitializationMode(c), fmi2OK);
        EXPECT(fmi->SetReal(c, IN, 2, u), fmi2OK);
        EXPECT(fmi->DoStep(c, 0.0, h, fmi2True), fmi2OK);
        EXPECT(fmi->GetReal(c, OUT, 5, before), fmi2OK);
        if (kind == 0) u[0] = NAN;
        if (kind == 1) u[1] = INFINITY;
        if (kind == 2) h = 0.0;
        if (kind == 3) u[1] = -1e6;           /* > the emergency stop */
        if (kind == 4) u[0] += 1e6;           /* 1e6 rad in 1 ms: 7.9e7 rpm out */
        EXPECT(fmi->SetReal(c, IN, 2, u), fmi2OK);
        EXPECT(fmi->DoStep(c, 1e-3, h, fmi2True), fmi2Error);
        refused++;
        EXPECT(fmi->GetReal(c, OUT, 5, after), fmi2OK);
        CHECK(memcmp(after, before, sizeof after) == 0);   /* the step changed nothing */
        EXPECT(fmi->GetBooleanStatus(c, fmi2Terminated, &terminated), fmi2OK);
        CHECK(terminated == fmi2True);
        EXPECT(fmi->GetRealStatus(c, fmi2LastSuccessfulTime, &time), fmi2OK);
        CHECK(time == 1e-3);
        u[0] = -19.26, u[1] = -100.0;         /* good inputs: the simulation has ended all the same */
        EXPECT(fmi->SetReal(c, IN, 2, u), fmi2OK);
        EXPECT(fmi->DoStep(c, 1e-3, 1e-3, fmi2True), fmi2Error);
        refused++;
    }
    EXPECT(fmi->Reset(c), fmi2OK);
    EXPECT(fmi->SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
    EXPECT(fmi->SetReal(c, IN, 2, bad_start), fmi2OK);
    EXPECT(fmi->EnterInitializationMode(c), fmi2OK);
    EXPECT(fmi->ExitInitializationMode(c), fmi2Error);
    EXPECT(fmi->SetReal(c, IN, 2, start), fmi2OK);
    EXPECT(fmi->DoStep(c, 0.0, 1e-3, fmi2True), fmi2Error);
    refused++;
    EXPECT(fmi->GetBooleanStatus(c, fmi2Terminated, &terminated), fmi2OK);
    CHECK(terminated == fmi2True);
    return 0;
}

static int one_cycle(const Fmi *fmi, const char *uri, const char *guid, int steps, int logging,
                     fmi2Real last[5], fmi2Real *sum) {
    const fmi2String categories[2] = {"logStatusWarning", "logNothing"};
    fmi2Real start[2] = {-20.0, -50.0}, initial[5], value[5], time;
    fmi2Boolean terminated;
    fmi2Status pending;
    fmi2Integer ignored;
    fmi2Component c = fmi->Instantiate("cycle", fmi2CoSimulation, guid, uri, &callbacks, fmi2False,
                                       logging);
    int failed;
    CHECK(c != NULL);
    EXPECT(fmi->SetDebugLogging(c, fmi2True, 1, categories), fmi2OK);
    EXPECT(fmi->SetDebugLogging(c, fmi2True, 2, categories), fmi2Error);   /* logNothing */
    EXPECT(fmi->SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
    EXPECT(fmi->SetReal(c, IN, 2, start), fmi2OK);
    EXPECT(fmi->SetReal(c, OUT, 1, start), fmi2Error);                     /* an output */
    EXPECT(fmi->EnterInitializationMode(c), fmi2OK);
    EXPECT(fmi->GetReal(c, OUT, 5, initial), fmi2OK);
    EXPECT(fmi->ExitInitializationMode(c), fmi2OK);
    if ((failed = steps_with_every_path(fmi, c, steps, last, sum))) return failed;

    EXPECT(fmi->GetRealStatus(c, fmi2LastSuccessfulTime, &time), fmi2OK);
    CHECK(time > 0.0);
    EXPECT(fmi->GetBooleanStatus(c, fmi2Terminated, &terminated), fmi2OK);
    CHECK(terminated == fmi2False);
    EXPECT(fmi->GetStatus(c, fmi2DoStepStatus, &pending), fmi2OK);
    EXPECT(fmi->GetStatus(c, fmi2PendingStatus, &pending), fmi2Discard);
    EXPECT(fmi->GetInteger(c, OUT, 1, &ignored), fmi2Error);
    EXPECT(fmi->GetDirectionalDerivative(c, OUT, 1, IN, 1, start, value), fmi2Error);
    EXPECT(fmi->CancelStep(c), fmi2Error);
    EXPECT(fmi->Terminate(c), fmi2OK);
    EXPECT(fmi->DoStep(c, time, 1e-3, fmi2True), fmi2Error);   /* terminated */

    /* a second start after fmi2Reset repeats the first */
    EXPECT(fmi->Reset(c), fmi2OK);
    EXPECT(fmi->SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
    EXPECT(fmi->SetReal(c, IN, 2, start), fmi2OK);
    EXPECT(fmi->EnterInitializationMode(c), fmi2OK);
    EXPECT(fmi->ExitInitializationMode(c), fmi2OK);
    EXPECT(fmi->GetReal(c, OUT, 5, value), fmi2OK);
    CHECK(memcmp(value, initial, sizeof value) == 0);

    if ((failed = refusals(fmi, c))) return failed;
    fmi->FreeInstance(c);
    return 0;
}

static int refused_instances(const Fmi *fmi, const char *uri, const char *bad_uri,
                             const char *guid) {
    CHECK(!fmi->Instantiate("corrupted", fmi2CoSimulation, guid, bad_uri, &callbacks, 0, 0));
    CHECK(!fmi->Instantiate("not a file", fmi2CoSimulation, guid, "http://host/resources",
                            &callbacks, 0, 0));
    CHECK(!fmi->Instantiate("exchange", fmi2ModelExchange, guid, uri, &callbacks, 0, 0));
    fmi->FreeInstance(NULL);
    return 0;
}

int main(int argc, char **argv) {
    fmi2Real first[5], last[5], first_sum = 0.0, sum;
    int cycles, steps, cycle, failed;
    void *lib;
    Fmi fmi = {0};
    if (argc != 7) {
        fprintf(stderr, "usage: %s LIBRARY RESOURCES_URI BAD_RESOURCES_URI GUID CYCLES STEPS\n",
                argv[0]);
        return 2;
    }
    cycles = atoi(argv[5]);
    steps = atoi(argv[6]);
    CHECK(cycles > 0 && steps >= 20);
    if (!(lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL))) {
        fprintf(stderr, "%s\n", dlerror());
        return 3;
    }
    if ((failed = load(lib, &fmi))) return failed;
    CHECK(strcmp(fmi.GetVersion(), "2.0") == 0 && strcmp(fmi.GetTypesPlatform(), "default") == 0);
    for (cycle = 0; cycle < cycles; cycle++) {
        echo = cycle == 0;
        if ((failed = one_cycle(&fmi, argv[2], argv[4], steps, cycle == 0, last, &sum)))
            return failed;
        if (cycle == 0) {
            memcpy(first, last, sizeof first);
            first_sum = sum;
        }
        CHECK(memcmp(first, last, sizeof first) == 0 && sum == first_sum);
    }
    echo = 1;
    if ((failed = refused_instances(&fmi, argv[2], argv[3], argv[4]))) return failed;
    CHECK(dlclose(lib) == 0);
    printf("cycles %d steps %d refused %d warnings %d errors %d sum %a last te %a\n", cycles,
           steps, refused, messages[fmi2Warning], messages[fmi2Error], first_sum, first[OUT_TE]);
    return 0;
}
