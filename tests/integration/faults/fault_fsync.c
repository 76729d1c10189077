/* tests/integration/faults/fault_fsync.c — LD_PRELOAD shim for the fault-injection tests: fsync
 * and fdatasync fail with the errno in $SELFCAL_FAULT_FSYNC_ERRNO (e.g. 5 = EIO, 28 = ENOSPC), as
 * a failing or full disk reports a write-back error. (write() itself is not interposed: glibc's
 * stdio calls it internally; a full disk is a small tmpfs instead, see test_cli_faults.py.) */
#include <errno.h>
#include <stdlib.h>

static int fault(void)
{
    const char *e = getenv("SELFCAL_FAULT_FSYNC_ERRNO");
    if (e == NULL || *e == '\0')
        return 0;
    errno = atoi(e);
    return -1;
}

int fsync(int fd)
{
    (void)fd;
    return fault();
}

int fdatasync(int fd)
{
    (void)fd;
    return fault();
}
