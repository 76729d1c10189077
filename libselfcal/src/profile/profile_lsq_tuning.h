/* profile_lsq_tuning.h — internal tuning switches of the profile least squares (not installed):
 * kernel choice and factor variant for the tests, threading and huge pages for the benchmarks.
 * Users reach the last two through environment variables read by sc_profile_lsq_plan_create
 * (SELFCAL_PROFILE_LSQ_ONE_THREAD=1, SELFCAL_PROFILE_LSQ_HUGE_PAGES=1; docs/profile-lsq.md). */
#ifndef SELFCAL_PROFILE_LSQ_TUNING_H
#define SELFCAL_PROFILE_LSQ_TUNING_H

#include "selfcal/profile_lsq.h"

/* Flags of sc_profile_lsq_plan_create_tuned. */
#define SC_PROFILE_LSQ_PORTABLE 1u /* portable kernels even where AVX2/FMA ones exist (testing) */
#define SC_PROFILE_LSQ_SERIAL 2u   /* one-sided banded factor even where the twisted one applies
                                      (testing; the twisted one halves time and memory) */
#define SC_PROFILE_LSQ_ONE_THREAD 4u /* no helper thread (by default, plans with 16 MB of factor
                                        or more have its pages faulted in by a second thread
                                        while the first factors; results are identical) */
#define SC_PROFILE_LSQ_HUGE_PAGES 8u /* factor in transparent huge pages: faster where recently
                                        freed memory is reused (~0.2 s at N = 10⁶, d = 101), much
                                        slower where a VM host must back fresh memory first */
#define SC_PROFILE_LSQ_EARLY_UNCERTAINTY 16u /* start the selected inversion (the O(N·d²) part of
                                        sc_profile_lsq_uncertainty) on a second thread as soon as
                                        the factor exists; uncertainty then only waits for it and
                                        finishes in O(N). +8·N bytes. Identical results. */

/* sc_profile_lsq_plan_create with flags (0 or an OR of the SC_PROFILE_LSQ_* flags above). */
sc_status sc_profile_lsq_plan_create_tuned(int n, int d1, int d2, double w1, double w2,
                                           unsigned flags, sc_profile_lsq_plan **out, sc_error *err);

#endif
