"""How the LinuxCNC tests run LinuxCNC's programs (halrun, and the linuxcnc script) with this
build's selfcal_xy.so, as test_hal.py does (its docstring says why):

- as root: as the unprivileged user `nobody` (created if missing), in a private mount namespace
  in which an overlay puts the build's module into rtapi_app's fixed module folder;
- as a user with password-less sudo: the same namespace through `sudo -n`, as that user;
- otherwise: only if the installed module is the build's own, else exit 77 (skipped).

One HAL session per machine: HalEnv takes the machine-wide lock test_hal.py takes."""
import fcntl
import filecmp
import os
import pwd
import shutil
import subprocess
import sys
import tempfile

MODULE_DIR = "/usr/lib/linuxcnc/modules"  # rtapi_app's fixed folder (Debian linuxcnc-uspace)


def _can_sudo():
    try:
        return subprocess.run(["sudo", "-n", "true"], capture_output=True, timeout=20).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


class HalEnv:
    def __init__(self, module, work):
        self.work = work
        os.makedirs(work, exist_ok=True)
        self.lock = os.open("/tmp/selfcal-linuxcnc-hal.lock", os.O_RDONLY | os.O_CREAT, 0o644)
        fcntl.flock(self.lock, fcntl.LOCK_EX)
        self.scratch = tempfile.mkdtemp(prefix="selfcal-hal-")
        os.chmod(self.scratch, 0o755)
        self.mods = os.path.join(self.scratch, "modules")
        os.mkdir(self.mods)
        shutil.copy(module, os.path.join(self.mods, "selfcal_xy.so"))
        os.chmod(os.path.join(self.mods, "selfcal_xy.so"), 0o644)
        self.home = os.path.join(self.scratch, "home")
        os.mkdir(self.home)
        installed = os.path.join(MODULE_DIR, "selfcal_xy.so")
        if os.geteuid() == 0:
            try:
                user = pwd.getpwnam("nobody")
            except KeyError:
                subprocess.run(["useradd", "--system", "--no-create-home", "--shell",
                                "/usr/sbin/nologin", "nobody"], check=True)
                user = pwd.getpwnam("nobody")
            os.chown(self.home, user.pw_uid, user.pw_gid)
            self.prefix, self.user = [], user
        elif _can_sudo():
            self.prefix, self.user = ["sudo", "-n"], pwd.getpwuid(os.getuid())
        elif os.path.exists(installed) and filecmp.cmp(installed, module, shallow=False):
            self.prefix, self.user = None, None
        else:
            print(f"SKIP: not root, no sudo, and {installed} is not this build's module "
                  "(rtapi_app loads modules from that folder only)")
            shutil.rmtree(self.scratch)
            sys.exit(77)

    RUN_PERIODS = """#!/bin/sh
# run_periods.sh PIN N: start the threads, wait until the counter PIN has grown by N (at most
# 60 s: a loaded machine may not run a non-realtime thread for a while), stop the threads.
c0=$(halcmd getp "$1")
halcmd start
end=$(( $(date +%s) + 60 ))
while :; do
  c=$(halcmd getp "$1")
  awk -v c="$c" -v c0="$c0" -v n="$2" 'BEGIN { exit !(c - c0 >= n) }' && break
  [ "$(date +%s)" -ge "$end" ] && break
  sleep 0.002
done
halcmd stop
"""

    def run_periods(self, pin, n):
        """A .hal line that runs the threads until the counter pin (a sum2 whose out feeds its
        in0, in1 = 1) has grown by at least n, then stops them (see RUN_PERIODS)."""
        path = os.path.join(self.scratch, "run_periods.sh")
        if not os.path.exists(path):
            with open(path, "w") as f:
                f.write(self.RUN_PERIODS)
            os.chmod(path, 0o755)
        return f"loadusr -w sh {path} {pin} {n}"

    def argv(self, cmd, cwd=None):
        """argv running the shell command `cmd` (a string) as the HAL user, HOME = self.home."""
        cd = f"cd {cwd} && " if cwd else ""
        if self.prefix is None:
            return ["sh", "-c", f"{cd}HOME={self.home} exec {cmd}"]
        inner = (f"mount -t overlay overlay -o lowerdir={self.mods}:{MODULE_DIR} {MODULE_DIR} && "
                 f"{cd}exec setpriv --reuid={self.user.pw_uid} --regid={self.user.pw_gid} "
                 f"--clear-groups env HOME={self.home} {cmd}")
        return self.prefix + ["unshare", "--mount", "--propagation", "private", "sh", "-c", inner]

    def public(self, path):
        """A world-readable copy of path in the scratch folder."""
        dst = os.path.join(self.scratch, os.path.basename(path))
        shutil.copyfile(path, dst)
        os.chmod(dst, 0o644)
        return dst

    def halrun(self, lines, name, timeout=120):
        """Runs a .hal script with halrun; returns (exit status, stdout, stderr), logged in work."""
        path = os.path.join(self.scratch, name + ".hal")
        with open(path, "w") as f:
            f.write("\n".join(lines) + "\n")
        os.chmod(path, 0o644)
        p = subprocess.run(self.argv(f"halrun -f {path}"), capture_output=True, text=True,
                           timeout=timeout)
        with open(os.path.join(self.work, name + ".log"), "w") as f:
            f.write(f"exit {p.returncode}\n--- stdout\n{p.stdout}\n--- stderr\n{p.stderr}")
        return p.returncode, p.stdout, p.stderr

    def close(self):
        shutil.rmtree(self.scratch, ignore_errors=True)
