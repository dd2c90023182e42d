/* The quasi-static RV reducer stepped from its TE map: the physics of the native FMU.
 *
 * Knows nothing of FMI (fmi2Functions.c maps the FMI calls onto it).  The TE
 * map is the one `rvfmu.core.steppers.te_map.TEMap` holds, read from the binary table
 * that `rvfmu.fmu.native` writes (layout in model.c); interpolating it and
 * stepping the reducer reproduce `TEMap.evaluate_one` and
 * `rvfmu.core.steppers.reducer_model.QuasiStaticReducer` operation for operation.
 */
#ifndef RVTE_MODEL_H
#define RVTE_MODEL_H

#include <stddef.h>

/* Kept out of the shared library's exports where the compiler can: only the fmi2 functions
 * are the FMU's interface, and a host may load other FMUs with functions of these names. */
#if defined __GNUC__ && !defined _WIN32
#pragma GCC visibility push(hidden)
#endif

#define RV_MESSAGE_SIZE 1024   /* room for any message of this file, a path included */

/* TE [rad] and input torque [N*m] over input angle x torque magnitude, two load branches. */
typedef struct {
    int points;                /* A: angle points over one output revolution */
    int levels;                /* T: torque levels */
    double ratio;              /* i = theta_in / theta_out */
    double rated_torque;       /* [N*m] */
    double momentary_factor;   /* x rated: above, the step is computed with a warning */
    double emergency_factor;   /* x rated: above, the step is refused */
    double period;             /* input angle of one output revolution [rad] */
    double per_radian;         /* angle points per radian of input */
    int speeds;                /* K: speeds of the load-free friction */
    double speed_scale;        /* the friction law's speed scale [rad/s at the input] */
    double allowable_speed;    /* the catalogue's allowable output speed [rad/s] */
    double speed_factor;       /* x allowable: above, the step is refused; above 1 x, a warning */
    char design[64];           /* the design's name, for the messages (NUL-terminated) */
    double *magnitude;         /* (T,) ascending torque magnitudes [N*m], the first 0 */
    double *te;                /* (2, T, A): branch 0 resisting loads, 1 driving loads [rad] */
    double *tau_in;            /* (2, T, A) [N*m] */
    double *friction;          /* (2, T, A): the Coulomb friction torque at the output [N*m] */
    double *drag_speed;        /* (K,) output speeds [rad/s], ascending, the first 0 */
    int temperatures;          /* M: lubricant temperatures of the load-free friction */
    double seal;               /* the seals' share of the load-free torque at the output [N*m] */
    double static_factor;      /* breakaway over running friction (Coulomb and seals) [1] */
    double stribeck_speed;     /* the breakaway law's speed [rad/s at the input] (> 0) */
    double *drag_temperature;  /* (M,) [C], ascending */
    double *drag;              /* (M, K) the load-free friction torque at the output [N*m] */
    double *load_free;         /* (K,) the load-free torque at the instance's temperature */
} TEMap;

/* The reducer's whole state, and its outputs at `time`. */
typedef struct {
    double time;        /* [s] */
    double theta_out;   /* [rad] */
    double omega_out;   /* [rad/s]: change of theta_out over the last step / its size */
    double te;          /* [rad] */
    double tau_in;      /* [N*m], friction included */
    double theta_in;    /* [rad]: the input angle of the last step */
    double p_loss;      /* [W]: the friction's power over the last step */
    double efficiency;  /* [1] over the last step (reducer_model.friction_step) */
} Reducer;

typedef enum { INPUT_OK = 0, INPUT_WARNING = 1, INPUT_REFUSED = 2 } InputCheck;

/* Read and check the table at `path`; 0 on success, else -1 with the reason in `message`. */
int te_map_read(const char *path, TEMap *map, char *message, size_t size);
void te_map_free(TEMap *map);

/* TE [rad], input torque [N*m] and the Coulomb friction torque at the output [N*m] at one
 * input angle [rad] and load torque [N*m]. */
void te_map_evaluate(const TEMap *map, double theta_in, double tau_load, double *te, double *tau_in,
                     double *friction);

/* The load-free friction torque at the output [N*m] at an output speed [rad/s], the lubricant at
 * the temperature of the last te_map_set_temperature (40 C after te_map_read). */
double te_map_load_free(const TEMap *map, double omega_out);

/* Read the load-free table at the lubricant temperature `temperature_C` [C] (linear between the
 * table's temperatures, at one of them its row exactly: TEMap.load_free_row); 0, or -1 with the
 * reason in `message` if it is not finite or outside the table's temperatures. */
int te_map_set_temperature(TEMap *map, double temperature_C, char *message, size_t size);

/* Outputs at `time` for the initial inputs: omega_out = 0. */
void reducer_initialize(Reducer *reducer, const TEMap *map, double time, double theta_in,
                        double tau_load);

/* Outputs at time + step_size (step_size > 0) for the inputs there. */
void reducer_step(Reducer *reducer, const TEMap *map, double time, double step_size,
                  double theta_in, double tau_load);

/* te [rad] in arcseconds. */
double te_arcsec(double te);

/* Whether the model can take these inputs (and, if check_step, this step size).
 * INPUT_REFUSED: an input not finite, a step size not > 0 or a load beyond the
 * emergency-stop class; INPUT_WARNING: a load beyond the momentary maximum class.
 * The reason goes to `message` (the texts of the pythonfmu FMU, rvfmu/fmu/slave.py). */
InputCheck reducer_check_inputs(const TEMap *map, double theta_in, double tau_load, int check_step,
                                double step_size, char *message, size_t size);

/* Whether the output speed a step implies, (theta_in - the last step's theta_in) / step_size /
 * ratio [rad/s], is one the model can take (rvfmu.core.reducer.limits.check_speed): INPUT_REFUSED beyond
 * speed_factor x the allowable output speed, INPUT_WARNING above it.  Finite inputs and a step
 * size > 0 (reducer_check_inputs passed them).  The reason goes to `message`. */
InputCheck reducer_check_speed(const TEMap *map, const Reducer *reducer, double theta_in,
                               double step_size, char *message, size_t size);

/* Python's repr() of a float (shortest text that reads back the same, "0.0", "nan", "-inf"). */
void format_number(double value, char *text, size_t size);

#if defined __GNUC__ && !defined _WIN32
#pragma GCC visibility pop
#endif

#endif
