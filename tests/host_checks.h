/* The checks both plain C hosts of the native FMU (native_host_cycles.c for FMI 2.0,
 * native3_host_cycles.c for FMI 3.0) make of every call: a call that must return a status,
 * a condition that must hold.  Either returns from the calling function with an exit code
 * after printing the line that failed. */
#ifndef RVTE_HOST_CHECKS_H
#define RVTE_HOST_CHECKS_H

#include <stdio.h>

#define EXPECT(call, status)                                                                      \
    do {                                                                                          \
        int got_ = (int)(call);                                                                   \
        if (got_ != (int)(status)) {                                                              \
            fprintf(stderr, "line %d: %s returned %d, not %d\n", __LINE__, #call, got_,           \
                    (int)(status));                                                               \
            return 11;                                                                            \
        }                                                                                         \
    } while (0)
#define CHECK(condition)                                                                          \
    do {                                                                                          \
        if (!(condition)) {                                                                       \
            fprintf(stderr, "line %d: %s does not hold\n", __LINE__, #condition);                 \
            return 12;                                                                            \
        }                                                                                         \
    } while (0)

#endif
