/* The loader of the sparse symmetric solver (sparse_sym.h): CHOLMOD and the BLAS/LAPACK it uses,
 * taken with dlopen at the first analysis (see sparse_sym_internal.h), and the address-space
 * headroom check made before loading them. */
#include "sparse_sym_internal.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#define SC_STR_(x) #x
#define SC_STR(x) SC_STR_(x)

static cholmod_api g_api;
static pthread_once_t g_api_once = PTHREAD_ONCE_INIT;

static void load_api(void)
{
    /* the CHOLMOD whose headers this was compiled with: its structures (cholmod_common,
     * cholmod_factor) change between major versions, so no other may be taken */
    void *h = dlopen("libcholmod.so." SC_STR(CHOLMOD_MAIN_VERSION), RTLD_NOW | RTLD_LOCAL);
    if (!h)
        return;
    enum { NSYM = 14 };
    void *sym[NSYM];
    static const char *names[NSYM] = {"cholmod_start",      "cholmod_finish",
                                      "cholmod_analyze",    "cholmod_analyze_p",
                                      "cholmod_amd",        "cholmod_factorize",
                                      "cholmod_solve2",     "cholmod_free_factor",
                                      "cholmod_free_dense", "dtrsm_",
                                      "dsymm_",             "dgemm_",
                                      "dpotri_",            "cholmod_allocate_dense"};
    for (int k = 0; k < NSYM; ++k)
        if (!(sym[k] = dlsym(h, names[k])))
            return;
    /* object pointer to function pointer: POSIX guarantees dlsym's results convert */
    void *slot[NSYM] = {&g_api.start,       &g_api.finish,     &g_api.analyze, &g_api.analyze_p,
                        &g_api.amd,         &g_api.factorize,  &g_api.solve2,  &g_api.free_factor,
                        &g_api.free_dense,  &g_api.dtrsm,      &g_api.dsymm,   &g_api.dgemm,
                        &g_api.dpotri,      &g_api.allocate_dense};
    for (int k = 0; k < NSYM; ++k)
        memcpy(slot[k], &sym[k], sizeof sym[k]);
    g_api.ok = 1;
}

/* OpenBLAS (loaded with CHOLMOD) reserves a buffer of 32-128 MiB per thread at its first call
 * and, when the address space limit (ulimit -v) refuses it, retries forever, then waits on its
 * workers at exit: a hang, not an error. Under a limit leaving less than this much room, the
 * solver is not loaded and the caller is told it lacks memory. */
#define SPSYM_MIN_HEADROOM ((double)768 * 1024 * 1024)

int sc_spsym_memory_headroom_ok(void)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_AS, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY)
        return 1;
    long pages = 0, page = sysconf(_SC_PAGESIZE);
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%ld", &pages) != 1)
            pages = 0;
        fclose(f);
    }
    double used = (double)pages * (double)(page > 0 ? page : 4096);
    return (double)rl.rlim_cur - used >= SPSYM_MIN_HEADROOM;
}

const cholmod_api *sc_spsym_api(void)
{
    pthread_once(&g_api_once, load_api);
    return g_api.ok ? &g_api : NULL;
}
