/* version.c — sc_version(): the version the library was built as (selfcal/version.h). */
#include "selfcal/version.h"

const char *sc_version(void)
{
    return SC_VERSION_STRING;
}
