/* PLACEHOLDER — replaced by the area that owns this command. */
#include <stdio.h>

#include "cli.h"

int cmd_simulate_profile(int argc, char **argv)
{
    (void)argc;
    fprintf(stderr, "selfcal %s: not built yet\n", argv[0]);
    return CLI_FAIL;
}
