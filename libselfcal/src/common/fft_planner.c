/* fft_planner.c — the lock around FFTW's planner (fft_planner.h). */
#include "fft_planner.h"

#include <pthread.h>

static pthread_mutex_t planner = PTHREAD_MUTEX_INITIALIZER;

void sc_fft_planner_lock(void) { pthread_mutex_lock(&planner); }

void sc_fft_planner_unlock(void) { pthread_mutex_unlock(&planner); }
