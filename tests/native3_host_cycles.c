/* A plain C FMI 3.0 host that puts the native reducer FMU through its whole life cycle,
 * over and over, for a memory checker (tests/test_fmu_native3.py runs it under valgrind and,
 * built with -fsanitize=address,undefined, with the FMU built the same way): the FMI 3.0
 * counterpart of native_host_cycles.c.
 *
 * Usage: native3_host_cycles LIBRARY RESOURCES_DIR/ BAD_RESOURCES_DIR/ TOKEN CYCLES STEPS
 *
 * Each cycle (`one_cycle`): fmi3InstantiateCoSimulation, fmi3SetDebugLogging (an unknown
 * category too), initial inputs, the initial unknowns in initialisation mode, exit; STEPS
 * steps of 1 ms with inputs that take every warning path of fmi3DoStep (a load beyond the
 * momentary class, an input speed above the allowable one); the FMU state got, serialised,
 * read back, set and freed, with a re-step that must repeat the step taken from it; calls the
 * FMU refuses; fmi3Terminate, fmi3Reset and a second start that must repeat the first
 * outputs; then (`refusals`) from a fresh start each input no retry can make valid (a NaN, an
 * infinite load, a zero step size, a load beyond the emergency-stop class, an input speed
 * beyond the limit) and bad initial inputs: each must end the simulation with fmi3Error and
 * terminateSimulation, the outputs unchanged, every later step refused; fmi3FreeInstance.  Every cycle must give the same outputs, to the bit.  Then
 * (`refused_instances`) instantiation on BAD_RESOURCES_DIR (a corrupted table), without a
 * resource path, with event mode and for model exchange: each must return NULL.
 *
 * Prints one line of counts and the last TE; exits 0 when every FMI call returned what it
 * should.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "host_checks.h"

enum { THETA_IN, TAU_LOAD, THETA_OUT, OMEGA_OUT, TE, TE_ARCSEC, TAU_IN, P_LOSS, EFFICIENCY,
       TIME };   /* value references */

static const fmi3ValueReference IN[2] = {THETA_IN, TAU_LOAD};
static const fmi3ValueReference OUT[7] = {THETA_OUT, OMEGA_OUT, TE, TE_ARCSEC, TAU_IN, P_LOSS,
                                          EFFICIENCY};
enum { OUT_TE = 2, NOUT = 7 };

static int messages[fmi3Fatal + 1];   /* log messages by status */
static int echo = 1;                  /* print them (the first cycle, the refused instances) */
static int refused = 0;               /* steps refused (fmi3Error), over all cycles */

/* fmi3LogMessageCallback: counts the messages by status, prints them while `echo` is set. */
static void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                        fmi3String message) {
    (void)env;
    if (status >= fmi3OK && status <= fmi3Fatal) messages[status]++;
    if (echo) fprintf(stderr, "[%s] %s\n", category, message);
}

#define FUNCTIONS(X)                                                                              \
    X(GetVersion) X(InstantiateCoSimulation) X(InstantiateModelExchange) X(SetDebugLogging)       \
    X(EnterInitializationMode) X(ExitInitializationMode) X(SetFloat64) X(GetFloat64) X(DoStep)    \
    X(GetFMUState) X(SetFMUState) X(FreeFMUState) X(SerializedFMUStateSize)                       \
    X(SerializeFMUState) X(DeserializeFMUState) X(GetInt32) X(GetDirectionalDerivative)           \
    X(EnterEventMode) X(Terminate) X(Reset) X(FreeInstance)

#define MEMBER(f) fmi3##f##TYPE *f;
typedef struct { FUNCTIONS(MEMBER) } Fmi;

static int load(void *lib, Fmi *fmi) {
#define LOAD(f)                                                                                   \
    if (!(fmi->f = (fmi3##f##TYPE *)dlsym(lib, "fmi3" #f))) {                                     \
        fprintf(stderr, "fmi3%s is not exported\n", #f);                                          \
        return 10;                                                                                \
    }
    FUNCTIONS(LOAD)
    return 0;
}

static fmi3Instance instantiate(const Fmi *fmi, const char *name, const char *token,
                                const char *resources, fmi3Boolean logging, fmi3Boolean events) {
    return fmi->InstantiateCoSimulation(name, token, resources, fmi3False, logging, events,
                                        fmi3False, NULL, 0, NULL, log_message, NULL);
}

/* Step from t by h with inputs u: the status, and whether the instance asks to terminate. */
static fmi3Status step(const Fmi *fmi, fmi3Instance c, fmi3Float64 t, fmi3Float64 h,
                       fmi3Boolean *terminate) {
    fmi3Boolean event, early;
    fmi3Float64 reached;
    return fmi->DoStep(c, t, h, fmi3True, &event, terminate, &early, &reached);
}

/* Roll back to `state` (taken after the step before) through its serialised bytes, re-take
 * the step with inputs `u` at time t: its outputs must be `value`. */
static int roll_back_and_re_step(const Fmi *fmi, fmi3Instance c, fmi3FMUState *state,
                                 const fmi3Float64 u[2], fmi3Float64 t,
                                 const fmi3Float64 value[NOUT]) {
    fmi3FMUState restored = NULL;
    fmi3Float64 again[NOUT];
    fmi3Boolean terminate;
    fmi3Byte *bytes;
    size_t size = 0;
    EXPECT(fmi->SerializedFMUStateSize(c, *state, &size), fmi3OK);
    CHECK((bytes = malloc(size)) != NULL);
    EXPECT(fmi->SerializeFMUState(c, *state, bytes, size - 1), fmi3Error);   /* too small */
    EXPECT(fmi->SerializeFMUState(c, *state, bytes, size), fmi3OK);
    EXPECT(fmi->DeserializeFMUState(c, bytes, size - 1, &restored), fmi3Error);
    EXPECT(fmi->DeserializeFMUState(c, bytes, size, &restored), fmi3OK);
    free(bytes);
    EXPECT(fmi->SetFMUState(c, restored), fmi3OK);
    EXPECT(fmi->SetFloat64(c, IN, 2, u, 2), fmi3OK);
    EXPECT(step(fmi, c, t, 1e-3, &terminate), fmi3OK);
    EXPECT(fmi->GetFloat64(c, OUT, NOUT, again, NOUT), fmi3OK);
    CHECK(memcmp(again, value, sizeof again) == 0);
    EXPECT(fmi->FreeFMUState(c, &restored), fmi3OK);
    EXPECT(fmi->FreeFMUState(c, state), fmi3OK);
    CHECK(*state == NULL && restored == NULL);
    return 0;
}

/* STEPS steps of 1 ms; the outputs of the last in `last`, the sum of the TE in `sum`. */
static int steps_with_every_path(const Fmi *fmi, fmi3Instance c, int steps,
                                 fmi3Float64 last[NOUT], fmi3Float64 *sum) {
    fmi3FMUState state = NULL;
    fmi3Float64 t = 0.0, value[NOUT];
    fmi3Boolean terminate;
    int k, failed;
    *sum = 0.0;
    for (k = 0; k < steps; k++, t += 1e-3) {
        fmi3Float64 u[2] = {0.37 * k - 20.0, 300.0 * (k % 7 - 3)};   /* both branches */
        if (k == steps / 2) u[1] = -1300.0;                   /* > momentary: warns */
        if (k == steps / 2 + 1) u[0] += 1.2;                  /* 124 rpm out > 70: warns */
        EXPECT(fmi->SetFloat64(c, IN, 2, u, 2), fmi3OK);
        EXPECT(step(fmi, c, t, 1e-3, &terminate), fmi3OK);
        CHECK(terminate == fmi3False);
        EXPECT(fmi->GetFloat64(c, OUT, NOUT, value, NOUT), fmi3OK);
        *sum += value[OUT_TE];
        if (k == steps / 4) {
            EXPECT(fmi->GetFMUState(c, &state), fmi3OK);
            EXPECT(fmi->GetFMUState(c, &state), fmi3OK);   /* the same state, overwritten */
        } else if (state && (failed = roll_back_and_re_step(fmi, c, &state, u, t, value))) {
            return failed;
        }
    }
    memcpy(last, value, sizeof value);
    return 0;
}

/* From a fresh start, one good step and then each input no retry can make valid: fmi3Error,
 * terminateSimulation, the outputs unchanged, and the next step (good inputs) refused too; then
 * bad initial inputs: fmi3ExitInitializationMode and every step after it refused. */
static int refusals(const Fmi *fmi, fmi3Instance c) {
    const fmi3Float64 start[2] = {-20.0, -50.0};
    fmi3Float64 before[NOUT], after[NOUT], bad_start[2] = {NAN, -50.0};
    fmi3Boolean terminate;
    int kind;
    for (kind = 0; kind < 5; kind++) {
        fmi3Float64 u[2] = {-19.63, -100.0}, h = 1e-3;
        EXPECT(fmi->Reset(c), fmi3OK);
        EXPECT(fmi->SetFloat64(c, IN, 2, start, 2), fmi3OK);
        EXPECT(fmi->EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0), fmi3OK);
        EXPECT(fmi->ExitInitializationMode(c), fmi3OK);
        EXPECT(fmi->SetFloat64(c, IN, 2, u, 2), fmi3OK);
        EXPECT(step(fmi, c, 0.0, h, &terminate), fmi3OK);
        EXPECT(fmi->GetFloat64(c, OUT, NOUT, before, NOUT), fmi3OK);
        if (kind == 0) u[0] = NAN;
        if (kind == 1) u[1] = INFINITY;
        if (kind == 2) h = 0.0;
        if (kind == 3) u[1] = -1e6;           /* > the emergency stop */
        if (kind == 4) u[0] += 1e6;           /* 1e6 rad in 1 ms: 7.9e7 rpm out */
        EXPECT(fmi->SetFloat64(c, IN, 2, u, 2), fmi3OK);
        terminate = fmi3False;
        EXPECT(step(fmi, c, 1e-3, h, &terminate), fmi3Error);
        CHECK(terminate == fmi3True);
        refused++;
        EXPECT(fmi->GetFloat64(c, OUT, NOUT, after, NOUT), fmi3OK);
        CHECK(memcmp(after, before, sizeof after) == 0);   /* the step changed nothing */
        u[0] = -19.26, u[1] = -100.0;         /* good inputs: the simulation has ended all the same */
        EXPECT(fmi->SetFloat64(c, IN, 2, u, 2), fmi3OK);
        terminate = fmi3False;
        EXPECT(step(fmi, c, 1e-3, 1e-3, &terminate), fmi3Error);
        CHECK(terminate == fmi3True);
        refused++;
    }
    EXPECT(fmi->Reset(c), fmi3OK);
    EXPECT(fmi->SetFloat64(c, IN, 2, bad_start, 2), fmi3OK);
    EXPECT(fmi->EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0), fmi3OK);
    EXPECT(fmi->ExitInitializationMode(c), fmi3Error);
    EXPECT(fmi->SetFloat64(c, IN, 2, start, 2), fmi3OK);
    terminate = fmi3False;
    EXPECT(step(fmi, c, 0.0, 1e-3, &terminate), fmi3Error);
    CHECK(terminate == fmi3True);
    refused++;
    return 0;
}

static int one_cycle(const Fmi *fmi, const char *resources, const char *token, int steps,
                     int logging, fmi3Float64 last[NOUT], fmi3Float64 *sum) {
    const fmi3String categories[2] = {"logStatusWarning", "logNothing"};
    fmi3Float64 start[2] = {-20.0, -50.0}, initial[NOUT], value[NOUT], time;
    fmi3ValueReference time_vr = TIME;
    fmi3Boolean terminate;
    fmi3Int32 ignored;
    fmi3Instance c = instantiate(fmi, "cycle", token, resources, logging, fmi3False);
    int failed;
    CHECK(c != NULL);
    EXPECT(fmi->SetDebugLogging(c, fmi3True, 1, categories), fmi3OK);
    EXPECT(fmi->SetDebugLogging(c, fmi3True, 2, categories), fmi3Error);   /* logNothing */
    EXPECT(fmi->SetFloat64(c, IN, 2, start, 2), fmi3OK);
    EXPECT(fmi->SetFloat64(c, OUT, 1, start, 1), fmi3Error);               /* an output */
    EXPECT(fmi->EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0), fmi3OK);
    EXPECT(fmi->GetFloat64(c, OUT, NOUT, initial, NOUT), fmi3OK);
    EXPECT(fmi->GetFloat64(c, OUT, NOUT, initial, NOUT - 1), fmi3Error);   /* too few values */
    EXPECT(fmi->ExitInitializationMode(c), fmi3OK);
    if ((failed = steps_with_every_path(fmi, c, steps, last, sum))) return failed;

    EXPECT(fmi->GetFloat64(c, &time_vr, 1, &time, 1), fmi3OK);
    CHECK(time > 0.0);
    EXPECT(fmi->GetInt32(c, OUT, 1, &ignored, 1), fmi3Error);
    EXPECT(fmi->GetDirectionalDerivative(c, OUT, 1, IN, 1, start, 1, value, 1), fmi3Error);
    EXPECT(fmi->EnterEventMode(c), fmi3Error);
    EXPECT(fmi->Terminate(c), fmi3OK);
    EXPECT(step(fmi, c, time, 1e-3, &terminate), fmi3Error);   /* terminated */

    /* a second start after fmi3Reset repeats the first */
    EXPECT(fmi->Reset(c), fmi3OK);
    EXPECT(fmi->SetFloat64(c, IN, 2, start, 2), fmi3OK);
    EXPECT(fmi->EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0), fmi3OK);
    EXPECT(fmi->ExitInitializationMode(c), fmi3OK);
    EXPECT(fmi->GetFloat64(c, OUT, NOUT, value, NOUT), fmi3OK);
    CHECK(memcmp(value, initial, sizeof value) == 0);

    if ((failed = refusals(fmi, c))) return failed;
    fmi->FreeInstance(c);
    return 0;
}

static int refused_instances(const Fmi *fmi, const char *resources, const char *bad_resources,
                             const char *token) {
    CHECK(!instantiate(fmi, "corrupted", token, bad_resources, fmi3False, fmi3False));
    CHECK(!instantiate(fmi, "no path", token, NULL, fmi3False, fmi3False));
    CHECK(!instantiate(fmi, "events", token, resources, fmi3False, fmi3True));
    CHECK(!fmi->InstantiateModelExchange("exchange", token, resources, fmi3False, fmi3False, NULL,
                                         log_message));
    fmi->FreeInstance(NULL);
    return 0;
}

int main(int argc, char **argv) {
    fmi3Float64 first[NOUT], last[NOUT], first_sum = 0.0, sum;
    int cycles, steps, cycle, failed;
    void *lib;
    Fmi fmi = {0};
    if (argc != 7) {
        fprintf(stderr, "usage: %s LIBRARY RESOURCES_DIR BAD_RESOURCES_DIR TOKEN CYCLES STEPS\n",
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
    CHECK(strcmp(fmi.GetVersion(), "3.0") == 0);
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
           steps, refused, messages[fmi3Warning], messages[fmi3Error], first_sum, first[OUT_TE]);
    return 0;
}
