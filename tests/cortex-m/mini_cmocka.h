/* mini_cmocka.h — the few cmocka macros test_core.c uses, for bare-metal runs (Cortex-M under
 * QEMU with semihosting: printf goes to the host through newlib's rdimon). Same semantics as
 * cmocka: a failed assertion prints where and why, ends the current test, and the group's
 * return value counts the failed tests. */
#ifndef MINI_CMOCKA_H
#define MINI_CMOCKA_H

#include <setjmp.h>
#include <stdio.h>

struct CMUnitTest {
    const char *name;
    void (*test_func)(void **state);
};

static jmp_buf mini_cmocka_jmp;

#define cmocka_unit_test(f) \
    {                       \
#f, f               \
    }
#define print_error(...) printf(__VA_ARGS__)
#define fail() longjmp(mini_cmocka_jmp, 1)
#define mini_cmocka_check(c, text)                                            \
    do {                                                                      \
        if (!(c)) {                                                           \
            printf("%s:%d: assertion failed: %s\n", __FILE__, __LINE__, text); \
            fail();                                                           \
        }                                                                     \
    } while (0)
#define assert_true(c) mini_cmocka_check((c), #c)
#define assert_false(c) mini_cmocka_check(!(c), "!(" #c ")")
#define assert_non_null(p) mini_cmocka_check((p) != NULL, #p " != NULL")
#define assert_int_equal(a, b)                                                                 \
    do {                                                                                       \
        long long a_ = (long long)(a), b_ = (long long)(b);                                    \
        if (a_ != b_) {                                                                        \
            printf("%s:%d: %s = %lld != %s = %lld\n", __FILE__, __LINE__, #a, a_, #b, b_);     \
            fail();                                                                            \
        }                                                                                      \
    } while (0)

static inline int mini_cmocka_run(const struct CMUnitTest *t, size_t n, const char *group)
{
    volatile int failed = 0;
    printf("[==========] %s: running %u test(s)\n", group, (unsigned)n);
    for (size_t k = 0; k < n; ++k) {
        void *state = NULL;
        printf("[ RUN      ] %s\n", t[k].name);
        if (setjmp(mini_cmocka_jmp) == 0) {
            t[k].test_func(&state);
            printf("[       OK ] %s\n", t[k].name);
        } else {
            printf("[  FAILED  ] %s\n", t[k].name);
            ++failed;
        }
    }
    printf("[==========] %s: %u test(s) run, %d failed\n", group, (unsigned)n, failed);
    return failed;
}

#define cmocka_run_group_tests(tests, setup, teardown) \
    mini_cmocka_run((tests), sizeof(tests) / sizeof((tests)[0]), #tests)

#endif
