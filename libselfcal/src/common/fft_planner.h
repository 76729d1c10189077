/* fft_planner.h — private: FFTW's planner (plan creation and destruction) is not thread-safe
 * (FFTW manual, "Thread safety": only fftw_execute is), so every plan the library makes or
 * destroys goes through this lock; two threads calibrating separate data with the DFT or an
 * exact grid method then never meet inside the planner. A lock, not state: nothing it guards
 * outlives the call. */
#ifndef SELFCAL_FFT_PLANNER_H
#define SELFCAL_FFT_PLANNER_H

void sc_fft_planner_lock(void);
void sc_fft_planner_unlock(void);

#endif
