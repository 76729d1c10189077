/* Minimal Cortex-M4 start for QEMU mps2-an386: a vector table whose reset entry enables the FPU
 * (CP10/CP11 full access) and enters newlib's _start (rdimon crt0: clears bss, sets up semihosting
 * I/O, calls main and exit). */
#include <stdint.h>

extern void _start(void);
extern uint32_t __stack;

void Reset_Handler(void);
void Fault_Handler(void);

void Reset_Handler(void)
{
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20; /* SCB->CPACR: CP10, CP11 full access */
    __asm volatile("dsb\n\tisb");
    _start();
    for (;;) {
    }
}

/* Any fault: stop here (the CTest timeout reports it: no pass line was printed). */
void Fault_Handler(void)
{
    for (;;) {
    }
}

__attribute__((section(".vectors"), used)) static void (*const vectors[16])(void) = {
    (void (*)(void))(&__stack), Reset_Handler, Fault_Handler, Fault_Handler, Fault_Handler,
    Fault_Handler, Fault_Handler, 0, 0, 0, 0, Fault_Handler, Fault_Handler, 0, Fault_Handler,
    Fault_Handler};
