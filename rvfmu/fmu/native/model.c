/* The quasi-static RV reducer stepped from its TE map (docs/model.md section 8).
 *
 * The TE map: rvfmu.core.steppers.te_map solves the quasi-static model once on a grid of
 * input angle (one output revolution) x output torque magnitude, on two branches
 * (resisting and driving loads: the TE jumps by the lost motion where the torque
 * changes sign).  Here it is read from the table the build wrote and interpolated
 * exactly as `TEMap.evaluate_one` does: periodic linear in the angle, linear in the
 * torque, the last two levels extrapolated beyond the grid.  Every operation below
 * is in Python's order, so that the results are the Python FMU's to the last bit
 * where the compiler does not fuse a*b + c (build with -ffp-contract=off; fused
 * multiply-adds would differ by a rounding error of the TE).  Only libc is needed.
 *
 * The table, resources/te_map.bin (all numbers little-endian; written by
 * rvfmu/fmu/native.py, whose docstring has the same layout):
 *
 *   offset               type              field
 *   0                    char[8]           magic "RVTEMAP\0"
 *   8                    uint32            format version, 4
 *   12                   uint32            A, angle points over one output revolution (>= 2)
 *   16                   uint32            T, torque levels (>= 2)
 *   20                   uint32            K, speeds of the load-free friction (>= 2)
 *   24                   float64           ratio i (> 0)
 *   32                   float64           rated torque [N*m] (> 0)
 *   40                   float64           momentary maximum class, x rated (> 0)
 *   48                   float64           emergency-stop class, x rated (>= the momentary)
 *   56                   float64           the friction law's speed scale [rad/s] (> 0)
 *   64                   float64           allowable output speed [rad/s] (> 0)
 *   72                   float64           speed factor, x allowable: beyond, refused (>= 1)
 *   80                   char[64]          the design's name, UTF-8, NUL-padded (a NUL in it)
 *   144                  uint32            M, lubricant temperatures of the load-free friction (>= 1)
 *   148                  uint32            0 (padding)
 *   152                  float64           the seals' torque at the output [N*m] (>= 0)
 *   160                  float64           static friction factor, breakaway / running (>= 1)
 *   168                  float64           the breakaway law's Stribeck speed [rad/s at the input] (> 0)
 *   176                  float64[T]        torque magnitudes [N*m], ascending, the first 0
 *   176 + 8T             float64[2][T][A]  te [rad]; branch 0 resisting, 1 driving loads
 *   176 + 8T + 16TA      float64[2][T][A]  tau_in [N*m]
 *   176 + 8T + 32TA      float64[2][T][A]  the Coulomb friction torque at the output [N*m]
 *   176 + 8T + 48TA      float64[K]        output speeds [rad/s], ascending, the first 0
 *   176 + 8T + 48TA + 8K float64[M]        lubricant temperatures [C], ascending
 *   ... + 8M             float64[M][K]     the load-free friction torque at the output [N*m]
 *   176 + 8T + 48TA + 8K + 8M + 8MK        end of file
 *
 * Version 3 added the speed limit (64..143): a version 2 table is refused, since the FMU
 * would then step any input speed without a word.  Version 4 added the load-free torque over
 * the lubricant's temperature and the breakaway (144..175): a version 3 table is refused.
 */
#ifdef __MINGW32__
#define __USE_MINGW_ANSI_STDIO 1   /* C99 printf and strtod (two-digit exponents), not msvcrt's */
#endif
#include "model.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define ARCSEC_RAD (PI / 180.0 / 3600.0)   /* rvfmu.core.base.units.ARCSEC, same expression */
#define RPM (2.0 * PI / 60.0)                /* rvfmu.core.base.units.RPM, same expression */

static const char MAGIC[8] = {'R', 'V', 'T', 'E', 'M', 'A', 'P', '\0'};
enum { FORMAT_VERSION = 4, HEADER_SIZE = 176, NAME_OFFSET = 80, NAME_SIZE = 64 };
#define REFERENCE_TEMPERATURE_C 40.0   /* rvfmu.core.laws.lubricant: the load-free torque's default */

/* -- reading the table ---------------------------------------------------------------- */

static uint32_t read_u32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static double read_f64(const unsigned char *p) {
    uint64_t bits = 0;
    double value;
    int k;
    for (k = 7; k >= 0; k--) bits = bits << 8 | p[k];
    memcpy(&value, &bits, sizeof value);   /* IEEE 754 binary64 on every FMI platform */
    return value;
}

static int fail(char *message, size_t size, const char *path, const char *reason) {
    snprintf(message, size, "TE map table %s: %s", path, reason);
    return -1;
}

/* Read the whole file; NULL with the reason in `message` if it cannot be read. */
static unsigned char *read_file(const char *path, size_t *length, char *message, size_t size) {
    FILE *file = fopen(path, "rb");
    unsigned char *data = NULL;
    long end;
    if (!file) {
        fail(message, size, path, "cannot be opened");
        return NULL;
    }
    if (fseek(file, 0, SEEK_END) == 0 && (end = ftell(file)) >= 0 && fseek(file, 0, SEEK_SET) == 0) {
        *length = (size_t)end;
        data = malloc(*length ? *length : 1);
        if (data && fread(data, 1, *length, file) != *length) {
            free(data);
            data = NULL;
        }
    }
    fclose(file);
    if (!data) fail(message, size, path, "cannot be read");
    return data;
}

static int all_finite(const double *values, size_t count) {
    size_t k;
    for (k = 0; k < count; k++)
        if (!isfinite(values[k])) return 0;
    return 1;
}

int te_map_read(const char *path, TEMap *map, char *message, size_t size) {
    size_t length = 0, A, T, K, M, cells, count, k;
    double *values;
    const unsigned char *p;
    unsigned char *data = read_file(path, &length, message, size);
    char reason[256];

    memset(map, 0, sizeof *map);
    if (!data) return -1;
    if (length < HEADER_SIZE || memcmp(data, MAGIC, sizeof MAGIC) != 0) {
        free(data);
        return fail(message, size, path, "not a TE map table (no RVTEMAP magic)");
    }
    if (read_u32(data + 8) != FORMAT_VERSION) {
        snprintf(reason, sizeof reason, "format version %lu, this FMU reads version %d",
                 (unsigned long)read_u32(data + 8), FORMAT_VERSION);
        free(data);
        return fail(message, size, path, reason);
    }
    A = read_u32(data + 12);
    T = read_u32(data + 16);
    K = read_u32(data + 20);
    M = read_u32(data + 144);
    /* sizes against the file length, by division: no product can overflow */
    if (A < 2 || T < 2 || K < 2 || M < 1 || K > (length - HEADER_SIZE) / 16
        || M > (length - HEADER_SIZE - 8 * K) / (8 * (K + 1))
        || T > (length - HEADER_SIZE - 8 * K - 8 * M * (K + 1)) / 8
        || A > (length - HEADER_SIZE - 8 * K - 8 * M * (K + 1) - 8 * T) / (48 * T)
        || length != HEADER_SIZE + 8 * T + 48 * T * A + 8 * K + 8 * M * (K + 1)) {
        snprintf(reason, sizeof reason, "%lu angle points x %lu torque levels, %lu speeds and %lu "
                 "temperatures do not fit its %lu bytes", (unsigned long)A, (unsigned long)T,
                 (unsigned long)K, (unsigned long)M, (unsigned long)length);
        free(data);
        return fail(message, size, path, reason);
    }
    cells = 2 * T * A;
    count = T + 3 * cells + K + M * (K + 1);
    values = malloc((count + K) * sizeof *values);   /* and the row at the temperature */
    if (!values) {
        free(data);
        return fail(message, size, path, "out of memory");
    }
    map->points = (int)A;
    map->levels = (int)T;
    map->ratio = read_f64(data + 24);
    map->rated_torque = read_f64(data + 32);
    map->momentary_factor = read_f64(data + 40);
    map->emergency_factor = read_f64(data + 48);
    map->speeds = (int)K;
    map->speed_scale = read_f64(data + 56);
    map->allowable_speed = read_f64(data + 64);
    map->speed_factor = read_f64(data + 72);
    memcpy(map->design, data + NAME_OFFSET, NAME_SIZE);
    map->temperatures = (int)M;
    map->seal = read_f64(data + 152);
    map->static_factor = read_f64(data + 160);
    map->stribeck_speed = read_f64(data + 168);
    for (k = 0, p = data + HEADER_SIZE; k < count; k++, p += 8) values[k] = read_f64(p);
    free(data);
    map->magnitude = values;
    map->te = values + T;
    map->tau_in = values + T + cells;
    map->friction = values + T + 2 * cells;
    map->drag_speed = values + T + 3 * cells;
    map->drag_temperature = values + T + 3 * cells + K;
    map->drag = values + T + 3 * cells + K + M;
    map->load_free = values + count;

    if (!(isfinite(map->ratio) && map->ratio > 0 && isfinite(map->rated_torque)
          && map->rated_torque > 0 && isfinite(map->momentary_factor) && map->momentary_factor > 0
          && isfinite(map->emergency_factor) && map->emergency_factor >= map->momentary_factor
          && isfinite(map->speed_scale) && map->speed_scale > 0
          && isfinite(map->allowable_speed) && map->allowable_speed > 0
          && isfinite(map->speed_factor) && map->speed_factor >= 1.0
          && isfinite(map->seal) && map->seal >= 0.0 && isfinite(map->static_factor)
          && map->static_factor >= 1.0 && isfinite(map->stribeck_speed)
          && map->stribeck_speed > 0))
        strcpy(reason, "ratio, rated torque, load classes, speed scale, allowable speed and "
               "Stribeck speed must be finite and > 0, the speed and static friction factors "
               ">= 1, the seals' torque >= 0");
    else if (memchr(map->design, '\0', sizeof map->design) == NULL)
        strcpy(reason, "the design's name must end in a NUL within its 64 bytes");
    else if (!all_finite(values, count))
        strcpy(reason, "non-finite values in the torque levels, te, tau_in or the friction");
    else if (map->magnitude[0] != 0.0 || map->drag_speed[0] != 0.0)
        strcpy(reason, "the first torque level and the first speed must be 0");
    else {
        reason[0] = '\0';
        for (k = 1; k < T; k++)
            if (!(map->magnitude[k] > map->magnitude[k - 1])) {
                strcpy(reason, "the torque levels must be strictly ascending");
                break;
            }
        for (k = 1; k < K && !reason[0]; k++)
            if (!(map->drag_speed[k] > map->drag_speed[k - 1])) {
                strcpy(reason, "the speeds must be strictly ascending");
                break;
            }
        for (k = 1; k < M && !reason[0]; k++)
            if (!(map->drag_temperature[k] > map->drag_temperature[k - 1])) {
                strcpy(reason, "the temperatures must be strictly ascending");
                break;
            }
    }
    if (reason[0]) {
        te_map_free(map);
        return fail(message, size, path, reason);
    }
    /* as TEMap.period and TEMap._per_radian */
    map->period = 2.0 * PI * map->ratio;
    map->per_radian = (double)A / map->period;
    /* the default temperature's row; a table without 40 C: its first until one is set (the
     * message then left unused: the table is good) */
    if (te_map_set_temperature(map, REFERENCE_TEMPERATURE_C, message, size) != 0)
        memcpy(map->load_free, map->drag, K * sizeof *map->load_free);
    return 0;
}

void te_map_free(TEMap *map) {
    free(map->magnitude);
    memset(map, 0, sizeof *map);
}

/* -- interpolation: TEMap.evaluate_one ------------------------------------------------- */

/* |x| mod y for y > 0, exactly as fmod computes it, with the sign of x: subtracting y * 2^k
 * from r when y * 2^k <= r < 2 y * 2^k is exact (Sterbenz), and so is halving y * 2^k.  Not
 * fmod itself: then the library needs no libm, which a tool building sources/ may not link. */
static double remainder_of(double x, double y) {
    double r = fabs(x), d = y;
    if (isinf(x)) return x - x;      /* NaN, as fmod */
    if (r < y) return x;
    while (d <= r / 2) d += d;       /* the largest y * 2^k <= r */
    for (;;) {
        if (r >= d) r -= d;          /* r < 2d before, r < d after */
        if (d == y) break;
        d *= 0.5;
    }
    return x < 0 ? -r : r;
}

/* Python's float `%` for a divisor y > 0: the remainder is >= 0 (CPython float_rem). */
static double python_mod(double x, double y) {
    double mod = remainder_of(x, y);
    if (mod != 0.0) {
        if (mod < 0) mod += y;
    } else {
        mod = 0.0;
    }
    return mod;
}

/* bisect.bisect_right: the index of the first level > x. */
static int bisect_right(const double *levels, int count, double x) {
    int lo = 0, hi = count;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (x < levels[mid]) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/* Linear in angle on two levels' rows, then linear in torque between them. */
static double bilinear(const double *lo, const double *hi, int i0, int i1, double wa, double wt) {
    double a = lo[i0] + wa * (lo[i1] - lo[i0]);
    return a + wt * (hi[i0] + wa * (hi[i1] - hi[i0]) - a);
}

void te_map_evaluate(const TEMap *map, double theta_in, double tau_load, double *te, double *tau_in,
                     double *friction) {
    const int A = map->points, last_level = map->levels - 2;
    double position = python_mod(theta_in, map->period) * map->per_radian;
    long whole = (long)position;          /* int(position): position >= 0 */
    double wa = position - (double)whole;
    int i0 = (int)(whole % A), i1 = i0 + 1 < A ? i0 + 1 : 0;
    int branch = tau_load > 0;            /* 1: driving loads; 0: resisting loads and no load */
    double magnitude = branch ? tau_load : -tau_load;
    const double *levels = map->magnitude;
    int j0 = bisect_right(levels, map->levels, magnitude) - 1;
    double wt;
    size_t row;                           /* te[branch][j0][0], tau_in[branch][j0][0] */
    j0 = j0 < 0 ? 0 : (j0 > last_level ? last_level : j0);   /* beyond the grid: extrapolate */
    wt = (magnitude - levels[j0]) / (levels[j0 + 1] - levels[j0]);
    row = ((size_t)branch * (size_t)map->levels + (size_t)j0) * (size_t)A;
    *te = bilinear(map->te + row, map->te + row + A, i0, i1, wa, wt);
    *tau_in = bilinear(map->tau_in + row, map->tau_in + row + A, i0, i1, wa, wt);
    *friction = bilinear(map->friction + row, map->friction + row + A, i0, i1, wa, wt);
}

/* TEMap.load_free_one: linear in the speed's magnitude, the last two speeds extrapolated. */
double te_map_load_free(const TEMap *map, double omega_out) {
    const double *speeds = map->drag_speed, *values = map->load_free;
    double speed = omega_out < 0 ? -omega_out : omega_out, w;
    int k = bisect_right(speeds, map->speeds, speed) - 1, last = map->speeds - 2;
    k = k > last ? last : k;
    w = (speed - speeds[k]) / (speeds[k + 1] - speeds[k]);
    return values[k] + w * (values[k + 1] - values[k]);
}

/* TEMap.load_free_row: linear in the temperature between the table's, its row at one of them. */
int te_map_set_temperature(TEMap *map, double temperature_C, char *message, size_t size) {
    const double *temperatures = map->drag_temperature;
    const int M = map->temperatures, K = map->speeds;
    const double *lo, *hi;
    char value[40], low[40], high[40];
    double w;
    int m, k;
    if (!(isfinite(temperature_C) && temperatures[0] <= temperature_C
          && temperature_C <= temperatures[M - 1])) {
        format_number(temperature_C, value, sizeof value);
        format_number(temperatures[0], low, sizeof low);
        format_number(temperatures[M - 1], high, sizeof high);
        snprintf(message, size, "temperature_C = %s: must be from %s to %s C (the temperatures of "
                 "the TE map's load-free table)", value, low, high);
        return -1;
    }
    m = bisect_right(temperatures, M, temperature_C) - 1;
    lo = map->drag + (size_t)m * (size_t)K;
    if (temperatures[m] == temperature_C) {
        memcpy(map->load_free, lo, (size_t)K * sizeof *map->load_free);
        return 0;
    }
    hi = lo + K;
    w = (temperature_C - temperatures[m]) / (temperatures[m + 1] - temperatures[m]);
    for (k = 0; k < K; k++) map->load_free[k] = lo[k] + w * (hi[k] - lo[k]);
    return 0;
}

/* -- the reducer: QuasiStaticReducer --------------------------------------------------- */

void reducer_initialize(Reducer *reducer, const TEMap *map, double time, double theta_in,
                        double tau_load) {
    double friction;
    te_map_evaluate(map, theta_in, tau_load, &reducer->te, &reducer->tau_in, &friction);
    reducer->time = time;
    reducer->theta_out = theta_in / map->ratio + reducer->te;
    reducer->omega_out = 0.0;
    reducer->theta_in = theta_in;
    reducer->p_loss = 0.0;
    reducer->efficiency = 0.0;
}

/* reducer_model.stribeck_decay: exp(-x) for x >= 0 in plain arithmetic (no libm), operation for
 * operation as the Python: x halved to <= 1/2, Taylor to the 16th power, squared back. */
#define STRIBECK_CUT 40.0   /* reducer_model.STRIBECK_CUT: beyond, 0 */
static double stribeck_decay(double x) {
    double term = 1.0, total = 1.0;
    int halvings = 0, k;
    if (x > STRIBECK_CUT) return 0.0;
    while (x > 0.5) {
        x *= 0.5;
        halvings++;
    }
    for (k = 1; k < 17; k++) {
        term = term * (-x) / (double)k;
        total = total + term;
    }
    for (k = 0; k < halvings; k++) total = total * total;
    return total;
}

/* reducer_model.friction_step: friction opposes the input's turning, Coulomb beyond the speed
 * scale and proportional to the speed within it; the part `breakaway_out` (the Coulomb contacts'
 * and the seals') at 1 + (static factor - 1) exp(-(omega_in / Stribeck speed)^2) times. */
static void friction_step(Reducer *reducer, const TEMap *map, double tau_map, double friction_out,
                          double omega_in, double breakaway_out) {
    double excess = map->static_factor - 1.0, sense, torque, passed;
    if (excess != 0.0) {
        double x = omega_in / map->stribeck_speed;
        friction_out = friction_out + excess * stribeck_decay(x * x) * breakaway_out;
    }
    sense = omega_in / map->speed_scale;
    sense = sense > 1.0 ? 1.0 : (sense < -1.0 ? -1.0 : sense);
    torque = sense * (friction_out / map->ratio);
    reducer->p_loss = torque * omega_in;
    passed = tau_map * omega_in;
    if (passed < 0.0)
        reducer->efficiency = -passed / (reducer->p_loss - passed);
    else if (passed > 0.0)
        reducer->efficiency = passed > reducer->p_loss ? (passed - reducer->p_loss) / passed : 0.0;
    else
        reducer->efficiency = 0.0;
    reducer->tau_in = tau_map - torque;
}

void reducer_step(Reducer *reducer, const TEMap *map, double time, double step_size,
                  double theta_in, double tau_load) {
    double theta_out, tau_map, coulomb, omega_in;
    te_map_evaluate(map, theta_in, tau_load, &reducer->te, &tau_map, &coulomb);
    theta_out = theta_in / map->ratio + reducer->te;
    if (step_size > 0) {
        reducer->omega_out = (theta_out - reducer->theta_out) / step_size;
        omega_in = (theta_in - reducer->theta_in) / step_size;
    } else {
        reducer->omega_out = omega_in = 0.0;
    }
    friction_step(reducer, map, tau_map, coulomb + te_map_load_free(map, omega_in / map->ratio),
                  omega_in, coulomb + map->seal);
    reducer->theta_out = theta_out;
    reducer->theta_in = theta_in;
    reducer->time = time + step_size;
}

double te_arcsec(double te) {
    return te / ARCSEC_RAD;
}

/* -- input checks: rvfmu/fmu/slave.py and rvfmu.core.reducer.limits.check_load ------------------ */

InputCheck reducer_check_inputs(const TEMap *map, double theta_in, double tau_load, int check_step,
                                double step_size, char *message, size_t size) {
    char value[40];
    double ratio;
    if (check_step && !(step_size > 0.0)) {
        format_number(step_size, value, sizeof value);
        snprintf(message, size, "communication step size = %s: must be a number > 0", value);
        return INPUT_REFUSED;
    }
    if (!isfinite(theta_in) || !isfinite(tau_load)) {
        const char *name = isfinite(theta_in) ? "tau_load" : "theta_in";
        format_number(isfinite(theta_in) ? tau_load : theta_in, value, sizeof value);
        snprintf(message, size, "input %s = %s: must be finite", name, value);
        return INPUT_REFUSED;
    }
    ratio = fabs(tau_load) / map->rated_torque;
    if (ratio > map->emergency_factor) {
        format_number(tau_load, value, sizeof value);
        snprintf(message, size, "input tau_load = %s: must be within +-%g x the rated torque %g N*m "
                 "(emergency-stop class, %g N*m): the small-displacement model does not hold "
                 "beyond", value, map->emergency_factor, map->rated_torque,
                 map->emergency_factor * map->rated_torque);
        return INPUT_REFUSED;
    }
    if (ratio > map->momentary_factor) {
        snprintf(message, size, "input tau_load = %g N*m is %.2g x the rated torque %g N*m, above "
                 "the momentary maximum class (%g x): the small-displacement model is stretched; "
                 "treat the results with care", tau_load, ratio, map->rated_torque,
                 map->momentary_factor);
        return INPUT_WARNING;
    }
    return INPUT_OK;
}

/* limits.check_speed, for the output speed the step implies: the same tests and the same texts
 * (the slave's `input ` prefix, the value shown is theta_in's). */
InputCheck reducer_check_speed(const TEMap *map, const Reducer *reducer, double theta_in,
                               double step_size, char *message, size_t size) {
    char value[40];
    double output_speed = (theta_in - reducer->theta_in) / step_size / map->ratio;
    double speed = fabs(output_speed), ratio = speed / map->allowable_speed;
    double limit_rpm = map->speed_factor * map->allowable_speed / RPM;
    format_number(theta_in, value, sizeof value);
    if (!(ratio <= map->speed_factor)) {   /* NaN too: an angle step of inf - inf */
        snprintf(message, size, "input theta_in = %s: is an output speed of %.4g rpm: must be "
                 "within %g x the allowable output speed %g rpm of %s (%g rpm out, %.6g rpm in)",
                 value, speed / RPM, map->speed_factor, map->allowable_speed / RPM, map->design,
                 limit_rpm, limit_rpm * map->ratio);
        return INPUT_REFUSED;
    }
    if (ratio > 1.0) {
        snprintf(message, size, "input theta_in = %s is an output speed of %.4g rpm, %.2g x the "
                 "allowable output speed %g rpm of %s: no rating covers it; treat the results "
                 "with care", value, speed / RPM, ratio, map->allowable_speed / RPM, map->design);
        return INPUT_WARNING;
    }
    return INPUT_OK;
}

void format_number(double value, char *text, size_t size) {
    char shortest[40], digits[24], fixed[48];
    const char *p;
    int precision, exponent, count = 0, k;
    size_t n = 0;
    if (isnan(value)) {
        snprintf(text, size, "nan");
        return;
    }
    if (isinf(value)) {
        snprintf(text, size, value > 0 ? "inf" : "-inf");
        return;
    }
    for (precision = 1; precision < 17; precision++) {   /* the fewest digits that read back */
        snprintf(shortest, sizeof shortest, "%.*e", precision - 1, value);
        if (strtod(shortest, NULL) == value) break;
    }
    snprintf(shortest, sizeof shortest, "%.*e", precision - 1, value);
    for (p = shortest; *p && *p != 'e'; p++)
        if (*p >= '0' && *p <= '9') digits[count++] = *p;
    exponent = atoi(p + 1);
    if (exponent < -4 || exponent >= 16) {   /* repr's switch to scientific notation */
        snprintf(text, size, "%s", shortest);
        return;
    }
    /* fixed notation with at least one digit after the point, as repr */
    if (signbit(value)) fixed[n++] = '-';
    if (exponent < 0) {
        fixed[n++] = '0';
        fixed[n++] = '.';
        for (k = -1; k > exponent; k--) fixed[n++] = '0';
        for (k = 0; k < count; k++) fixed[n++] = digits[k];
    } else {
        for (k = 0; k <= exponent; k++) fixed[n++] = k < count ? digits[k] : '0';
        fixed[n++] = '.';
        if (count > exponent + 1)
            for (k = exponent + 1; k < count; k++) fixed[n++] = digits[k];
        else
            fixed[n++] = '0';
    }
    fixed[n] = '\0';
    snprintf(text, size, "%s", fixed);
}
