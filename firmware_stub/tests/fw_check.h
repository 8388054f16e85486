/* Minimal check macros for the firmware unit tests (no framework). */
#ifndef FW_CHECK_H
#define FW_CHECK_H

#include <math.h>
#include <stdio.h>

static int fw_failures = 0;

#define CHECK(cond, ...)                                          \
    do {                                                          \
        if (!(cond)) {                                            \
            fprintf(stderr, "%s:%d: FAIL: ", __FILE__, __LINE__); \
            fprintf(stderr, __VA_ARGS__);                         \
            fputc('\n', stderr);                                  \
            ++fw_failures;                                        \
        }                                                         \
    } while (0)

#define CHECK_NEAR(got, want, tol, what)                                                   \
    CHECK(fabsf((float)(got) - (float)(want)) <= (float)(tol), "%s: got %.9g, want %.9g (tol %g)", \
          (what), (double)(got), (double)(want), (double)(tol))

#define FW_REPORT(name)                                                   \
    (fw_failures == 0 ? (printf("%s: all checks passed\n", (name)), 0)    \
                      : (fprintf(stderr, "%s: %d check(s) failed\n", (name), fw_failures), 1))

#endif
