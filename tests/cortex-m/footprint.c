/* The correction core alone on a Cortex-M4, without any C library: a vector table, one static
 * table, load it from a (here empty) image and correct one position. arm-none-eabi-size of this
 * program is the core's code and data footprint, the table's RAM included. */
#include <stdint.h>

#include "selfcal/correct.h"

extern uint32_t __stack;
void Reset_Handler(void);

static sc_corr_table table;             /* bss: the table, fixed size */
static uint8_t image[64];               /* would come from flash or a download */
volatile double result_mm[3];
volatile unsigned result_status;

void Reset_Handler(void)
{
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20; /* enable the FPU */
    int rc = sc_corr_load(&table, image, sizeof image);
    double in[3] = {1.0, 2.0, 0.0}, out[3];
    result_status = sc_corr_apply(&table, SC_CORR_MEASURE, in, out) | (unsigned)(rc & 0xFF) << 8;
    result_status |= sc_corr_apply_inverse(&table, in, out, 3);
    result_mm[0] = out[0];
    result_mm[1] = out[1];
    result_mm[2] = out[2];
    for (;;) {
    }
}

__attribute__((section(".vectors"), used)) static void (*const vectors[2])(void) = {
    (void (*)(void))(&__stack), Reset_Handler};
