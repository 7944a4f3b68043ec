/* Tiny test harness for the firmware unit tests: CHECK records a failure and continues, so one run
 * reports every broken expectation; the test's main returns t1_test_report(). */
#ifndef T1_TEST_H
#define T1_TEST_H

#include <math.h>
#include <stdio.h>

static int t1_test_failures = 0;
static int t1_test_checks = 0;

#define CHECK(cond)                                                            \
  do {                                                                         \
    ++t1_test_checks;                                                          \
    if (!(cond)) {                                                             \
      ++t1_test_failures;                                                      \
      fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
    }                                                                          \
  } while (0)

#define CHECK_NEAR(a, b, tol)                                                                                          \
  do {                                                                                                                 \
    const double t1_a_ = (double)(a), t1_b_ = (double)(b), t1_tol_ = (double)(tol);                                    \
    ++t1_test_checks;                                                                                                  \
    if (!(fabs(t1_a_ - t1_b_) <= t1_tol_)) {                                                                           \
      ++t1_test_failures;                                                                                              \
      fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.9g, %s = %.9g, tol %.3g\n", __FILE__, __LINE__, #a, t1_a_, #b, \
              t1_b_, t1_tol_);                                                                                         \
    }                                                                                                                  \
  } while (0)

static int t1_test_report(const char* name) {
  printf("%s: %d checks, %d failures\n", name, t1_test_checks, t1_test_failures);
  return t1_test_failures == 0 ? 0 : 1;
}

#endif /* T1_TEST_H */
