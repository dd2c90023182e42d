/* What the FMI 2.0 and FMI 3.0 layers share (instance.h): the model's side of an instance. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instance.h"

const char *const CATEGORY_NAMES[CATEGORIES] = {"logEvents", "logStatusWarning", "logStatusError"};

static const char STATE_TAG[8] = {'R', 'V', 'T', 'E', 'S', 'T', '2', '\0'};
typedef struct {
    char tag[8];
    State state;
} SerializedState;

void core_reset(Core *core) {
    memset(&core->state, 0, sizeof core->state);
    core->state.mode = INSTANTIATED;
    core->temperature_C = TEMPERATURE_START;
    core->load_warned = core->speed_warned = core->warnings = core->logged = 0;
    core->failed[0] = '\0';
}

static int category_index(const char *name) {
    int category;
    for (category = 0; category < CATEGORIES; category++)
        if (name && strcmp(name, CATEGORY_NAMES[category]) == 0) return category;
    return -1;
}

long core_set_logging(Core *core, int on, size_t n, const char *const categories[]) {
    size_t k;
    int category;
    if (n == 0) {
        for (category = 0; category < CATEGORIES; category++) core->logging[category] = on;
        return -1;
    }
    for (k = 0; k < n; k++) {
        if ((category = category_index(categories[k])) < 0) return (long)k;
        core->logging[category] = on;
    }
    return -1;
}

State *core_copy_state(const State *state, void *into) {
    State *copy = into ? into : malloc(sizeof *copy);
    if (copy) memcpy(copy, state, sizeof *copy);
    return copy;
}

/* Keep a warning for the layer to log, if this instance has not logged its kind before. */
static void warn(Core *core, int *warned, const char *message) {
    if (*warned || core->warnings >= WARNINGS) return;
    *warned = 1;
    snprintf(core->warning[core->warnings++], RV_MESSAGE_SIZE, "%s", message);
}

/* The inputs (and, if check_step, the step size and the speed it implies) checked: INPUT_REFUSED
 * with the reason in `core->failed`, else the warnings kept (each kind once per instance). */
static InputCheck check_inputs(Core *core, int check_step, double step_size, const char *prefix) {
    char message[RV_MESSAGE_SIZE];
    State *s = &core->state;
    InputCheck load = reducer_check_inputs(&core->map, s->theta_in, s->tau_load, check_step,
                                           step_size, message, sizeof message), speed = INPUT_OK;
    core->warnings = core->logged = 0;
    if (load == INPUT_WARNING) warn(core, &core->load_warned, message);
    if (load != INPUT_REFUSED && check_step) {
        speed = reducer_check_speed(&core->map, &s->reducer, s->theta_in, step_size, message,
                                    sizeof message);
        if (speed == INPUT_WARNING) warn(core, &core->speed_warned, message);
    }
    if (load != INPUT_REFUSED && speed != INPUT_REFUSED) return INPUT_OK;
    core->warnings = 0;   /* the step is not taken: nothing of it to warn of */
    snprintf(core->failed, sizeof core->failed, "%s%s", prefix, message);
    return INPUT_REFUSED;
}

InputCheck core_exit_initialization(Core *core) {
    State *s = &core->state;
    char message[RV_MESSAGE_SIZE];
    InputCheck check;
    if (te_map_set_temperature(&core->map, core->temperature_C, message, sizeof message) != 0) {
        s->mode = STEPPING;
        core->warnings = core->logged = 0;
        snprintf(core->failed, sizeof core->failed, "initialisation failed: %s", message);
        return INPUT_REFUSED;
    }
    check = check_inputs(core, 0, 0.0, "initialisation failed: ");
    s->mode = STEPPING;
    if (check != INPUT_REFUSED)
        reducer_initialize(&s->reducer, &core->map, s->reducer.time, s->theta_in, s->tau_load);
    return check;
}

InputCheck core_step(Core *core, double time, double step_size) {
    State *s = &core->state;
    InputCheck check;
    core->warnings = core->logged = 0;
    if (core->failed[0]) return INPUT_REFUSED;
    check = check_inputs(core, 1, step_size, "");
    if (check != INPUT_REFUSED)
        reducer_step(&s->reducer, &core->map, time, step_size, s->theta_in, s->tau_load);
    return check;
}

const char *core_next_warning(Core *core) {
    return core->logged < core->warnings ? core->warning[core->logged++] : NULL;
}

int core_terminated(const Core *core) { return core->failed[0] != '\0'; }

void core_update_initial_unknowns(Core *core) {
    char ignored[RV_MESSAGE_SIZE];
    State *s = &core->state;
    if (s->mode != INITIALIZATION) return;
    if (reducer_check_inputs(&core->map, s->theta_in, s->tau_load, 0, 0.0, ignored,
                             sizeof ignored) != INPUT_REFUSED)
        reducer_initialize(&s->reducer, &core->map, s->reducer.time, s->theta_in, s->tau_load);
}

int core_get(const Core *core, unsigned vr, double *value) {
    const Reducer *r = &core->state.reducer;
    switch (vr) {
    case THETA_IN: *value = core->state.theta_in; return 0;
    case TAU_LOAD: *value = core->state.tau_load; return 0;
    case THETA_OUT: *value = r->theta_out; return 0;
    case OMEGA_OUT: *value = r->omega_out; return 0;
    case TE: *value = r->te; return 0;
    case TE_ARCSEC: *value = te_arcsec(r->te); return 0;
    case TAU_IN: *value = r->tau_in; return 0;
    case P_LOSS: *value = r->p_loss; return 0;
    case EFFICIENCY: *value = r->efficiency; return 0;
    case TEMPERATURE_C: *value = core->temperature_C; return 0;
    default: return -1;
    }
}

int core_set(Core *core, unsigned vr, double value) {
    if (vr == TEMPERATURE_C) {   /* fixed: read into the map when initialisation ends */
        if (core->state.mode != INSTANTIATED && core->state.mode != INITIALIZATION) return 2;
        core->temperature_C = value;
        return 0;
    }
    if (vr == THETA_IN) core->state.theta_in = value;
    else if (vr == TAU_LOAD) core->state.tau_load = value;
    else return vr < VARIABLES ? 1 : -1;
    return 0;
}

size_t core_serialized_size(void) { return sizeof(SerializedState); }

void core_serialize(const State *state, unsigned char *bytes) {
    SerializedState serialized;
    memset(&serialized, 0, sizeof serialized);
    memcpy(serialized.tag, STATE_TAG, sizeof STATE_TAG);
    memcpy(&serialized.state, state, sizeof(State));
    memcpy(bytes, &serialized, sizeof serialized);
}

int core_deserialize(const unsigned char *bytes, size_t size, State *state) {
    SerializedState serialized;
    if (size != sizeof serialized) return -1;
    memcpy(&serialized, bytes, sizeof serialized);
    if (memcmp(serialized.tag, STATE_TAG, sizeof STATE_TAG) != 0
        || (int)serialized.state.mode < INSTANTIATED || (int)serialized.state.mode > TERMINATED)
        return -1;
    memcpy(state, &serialized.state, sizeof(State));
    return 0;
}
