/* What the FMI 2.0 and FMI 3.0 layers of the native RV reducer FMU share.
 *
 * fmi2Functions.c and fmi3Functions.c map the calls of their standard onto
 * this; it knows the FMU's variables, modes, inputs check, state bytes and
 * log categories, and nothing of either standard's types, so that the two FMUs
 * behave alike by construction (the same refusals, the same messages, the same
 * state).  Logging stays in the layers: each standard has its own logger.
 */
#ifndef RVTE_INSTANCE_H
#define RVTE_INSTANCE_H

#include <stddef.h>

#include "model.h"

#if defined __GNUC__ && !defined _WIN32
#pragma GCC visibility push(hidden)   /* as model.h: only the fmi functions are exported */
#endif

#define TABLE_NAME "te_map.bin"

/* The variables by value reference (rvfmu/fmu/native.py writes both model descriptions in
 * this order): inputs theta_in [rad], tau_load [N*m]; outputs theta_out [rad], omega_out
 * [rad/s], te [rad], te_arcsec [arcsec], tau_in [N*m], P_loss [W], efficiency [1]. */
enum { THETA_IN, TAU_LOAD, THETA_OUT, OMEGA_OUT, TE, TE_ARCSEC, TAU_IN, P_LOSS, EFFICIENCY,
       VARIABLES };
/* The one parameter: the lubricant's temperature [C], fixed, start 40; its value reference is
 * the pythonfmu FMU's (rvfmu/fmu/native.py checks it), after that FMU's other parameters. */
enum { TEMPERATURE_C = 18 };
#define TEMPERATURE_START 40.0

/* STEPPING is FMI 2.0's slave-initialised state and FMI 3.0's step mode. */
typedef enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED } Mode;

enum { LOG_EVENTS, LOG_WARNING, LOG_ERROR, CATEGORIES };
extern const char *const CATEGORY_NAMES[CATEGORIES];

/* Everything an FMU state holds (fmi2GetFMUstate / fmi3GetFMUState copy it whole). */
typedef struct {
    Mode mode;
    double theta_in, tau_load;   /* inputs */
    Reducer reducer;             /* outputs, and the time and angles of the last step */
} State;

enum { WARNINGS = 2 };   /* a step can warn of its load and of its speed */

/* One instance's model: its table, its state, what it has logged and refused. */
typedef struct {
    TEMap map;
    State state;
    double temperature_C;                /* the parameter [C]; the map's row read at it */
    int logging[CATEGORIES];             /* which categories reach the host's logger */
    int load_warned;                     /* the momentary-class warning was logged */
    int speed_warned;                    /* the allowable-speed warning was logged */
    int warnings, logged;                /* warnings of the last call; those handed out */
    char warning[WARNINGS][RV_MESSAGE_SIZE];
    char failed[RV_MESSAGE_SIZE + 32];   /* why the simulation ended; empty while it goes on */
} Core;

/* Back to the start values, the table kept. */
void core_reset(Core *core);

/* Switch the log categories named (all of them if n is 0) on or off: -1, or the index in
 * `categories` of a name that is no category (those before it are switched). */
long core_set_logging(Core *core, int on, size_t n, const char *const categories[]);

/* A copy of `state` in `into`, or in a new allocation if `into` is NULL (the FMU states the
 * host holds); NULL if out of memory. */
State *core_copy_state(const State *state, void *into);

/* Leave initialisation mode: the load-free table read at temperature_C, the outputs from the
 * initial inputs.  INPUT_REFUSED: a temperature outside the table's or inputs the model cannot
 * take, `core->failed` to log as an error, and every later step is refused until core_reset.  Otherwise the outputs are set and any warning waits in core_next_warning. */
InputCheck core_exit_initialization(Core *core);

/* One step from `time` [s] of `step_size` [s] with the inputs set.  INPUT_REFUSED: not taken
 * (the state unchanged), the reason in `core->failed`; the simulation has ended: no retry can
 * make a NaN, an infinite value, a load or a speed beyond the design's limits or a step size
 * that is not > 0 valid, so every later step is refused with the same reason until core_reset
 * (a host that retried a refused step would otherwise loop for ever).  Otherwise taken, and
 * any warning (a load above the momentary class, a speed above the allowable one: each once
 * per instance) waits in core_next_warning. */
InputCheck core_step(Core *core, double time, double step_size);

/* The next warning of the last call to log (then forgotten), or NULL. */
const char *core_next_warning(Core *core);

/* Whether the simulation has ended (a refused input): fmi2Terminated, terminateSimulation. */
int core_terminated(const Core *core);

/* In initialisation mode, the outputs follow the inputs (they are initial unknowns). */
void core_update_initial_unknowns(Core *core);

/* The value of the variable `vr`; 0, or -1 if there is no such variable. */
int core_get(const Core *core, unsigned vr, double *value);

/* Set the input or parameter `vr`; 0, 1 if `vr` is an output, 2 if it is the parameter after
 * initialisation (fixed), -1 if there is no such variable. */
int core_set(Core *core, unsigned vr, double value);

/* A state as bytes: this platform's, tagged; a state goes back to the FMU that wrote it. */
size_t core_serialized_size(void);
void core_serialize(const State *state, unsigned char *bytes);
/* 0, or -1 if the `size` bytes are not a state of this FMU. */
int core_deserialize(const unsigned char *bytes, size_t size, State *state);

#if defined __GNUC__ && !defined _WIN32
#pragma GCC visibility pop
#endif

#endif
