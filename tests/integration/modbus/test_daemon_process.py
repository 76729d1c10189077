#!/usr/bin/env python3
"""The selfcald binary as systemd runs it: the notify protocol on a unix datagram socket we
listen on (READY=1, WATCHDOG=1 at half of $WATCHDOG_USEC, RELOADING=1 then READY=1 on SIGHUP,
STOPPING=1 on SIGTERM), the example configuration file, and the exit statuses (0 on SIGTERM and
SIGINT, 2 on bad input: options, configuration, missing or corrupt table; 1 when the port is taken).
usage: test_daemon_process.py SELFCAL_CLI SELFCALD WORKDIR"""
import os
import signal
import socket
import subprocess
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
from sclib import Daemon, check, make_table  # noqa: E402

cli, selfcald, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)
table, _ = make_table(cli, work, "proc", n=5, pitch=1.0)
example = os.path.join(here, "..", "..", "..", "runtime", "selfcald.conf.example")

# 1. Notify protocol.
sock_path = os.path.join(work, "notify.sock")
if os.path.exists(sock_path):
    os.unlink(sock_path)
ns = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
ns.bind(sock_path)
ns.settimeout(5)
env = dict(os.environ, NOTIFY_SOCKET=sock_path, WATCHDOG_USEC="200000")
log = open(os.path.join(work, "proc.log"), "w")
p = subprocess.Popen([selfcald, "--config", example, "--table", table, "--modbus-tcp",
                      "127.0.0.1:0"], env=env, stderr=log)
msgs = []


def recv_until(pred, timeout=5):
    end = time.time() + timeout
    while time.time() < end:
        ns.settimeout(max(0.01, end - time.time()))
        try:
            m = ns.recv(4096).decode()
        except socket.timeout:
            break
        msgs.append((time.time(), m))
        if pred(m):
            return m
    return None


try:
    m = recv_until(lambda m: "READY=1" in m)
    check(m is not None, f"no READY=1: {msgs}")
    t0 = time.time()
    msgs.clear()
    time.sleep(1.0)
    recv_until(lambda m: False, timeout=0.05)
    wd = [t for t, m in msgs if m == "WATCHDOG=1"]
    # Half of 200 ms = every 100 ms: about 10 in one second.
    check(5 <= len(wd) <= 15, f"{len(wd)} WATCHDOG=1 in 1 s (expected about 10)")
    p.send_signal(signal.SIGHUP)
    check(recv_until(lambda m: m == "RELOADING=1") is not None, "no RELOADING=1 on SIGHUP")
    m = recv_until(lambda m: "READY=1" in m)
    check(m is not None and "reloaded" in m, f"no READY=1 after the reload: {m}")
    p.send_signal(signal.SIGTERM)
    check(recv_until(lambda m: m == "STOPPING=1") is not None, "no STOPPING=1 on SIGTERM")
    rc = p.wait(5)
    check(rc == 0, f"exit status {rc} after SIGTERM")
finally:
    if p.poll() is None:
        p.kill()
    ns.close()
    log.close()

# 2. SIGINT stops cleanly too.
d = Daemon(selfcald, table)
d.signal(signal.SIGINT)
check(d.p.wait(5) == 0, "exit status after SIGINT")
d.stop()

# 3. Exit statuses on bad input (2) and on a taken port (1).
def status(args):
    r = subprocess.run([selfcald] + args, capture_output=True, text=True, timeout=10)
    return r.returncode, r.stderr


rc, err = status(["--modbus-tcp", "127.0.0.1:0"])
check(rc == 2 and "--table" in err, f"no table: {rc} {err}")
rc, err = status(["--table", table, "--mode", "sideways"])
check(rc == 2 and "sideways" in err, f"bad mode: {rc} {err}")
rc, err = status(["--table", os.path.join(work, "missing.lut"), "--modbus-tcp", "127.0.0.1:0"])
check(rc == 2 and "missing.lut" in err, f"missing table: {rc} {err}")
bad = os.path.join(work, "corrupt.lut")
blob = bytearray(open(table, "rb").read())
blob[-1] ^= 1
open(bad, "wb").write(blob)
rc, err = status(["--table", bad, "--modbus-tcp", "127.0.0.1:0"])
check(rc == 2 and "corrupt.lut" in err, f"corrupt table: {rc} {err}")
conf = os.path.join(work, "bad.conf")
open(conf, "w").write("table = x.lut\nunit-id = 300\n")
rc, err = status(["--config", conf])
check(rc == 2 and "bad.conf:2:" in err, f"bad config: {rc} {err}")
# a configuration saved with a UTF-8 byte-order mark reads as without; a directory or a NUL byte
# is said as such (a directory used to read as an empty configuration)
open(conf, "wb").write(b"\xef\xbb\xbftable = " + os.path.join(work, "missing.lut").encode() + b"\n")
rc, err = status(["--config", conf])
check(rc == 2 and "missing.lut" in err and "unknown" not in err, f"config with a BOM: {rc} {err}")
rc, err = status(["--config", work])
check(rc == 2 and "is a directory" in err, f"config is a directory: {rc} {err}")
open(conf, "wb").write(b"# ok\nta\0ble = x.lut\n")
rc, err = status(["--config", conf])
check(rc == 2 and "bad.conf:2: NUL byte" in err, f"config with a NUL byte: {rc} {err}")
# an endless configuration (a pipe of blank lines) ends: refused past 100 000 lines
r = subprocess.run(["sh", "-c", 'yes "" | "$1" --config /dev/stdin', "sh", selfcald],
                   capture_output=True, text=True, timeout=60)
check(r.returncode == 2 and "more than 100000 lines" in r.stderr, f"endless config: {r.returncode} {r.stderr}")
# --help and --version must reach stdout (exit 1 with /dev/full, as selfcal does)
for opt in ("--help", "--version"):
    with open("/dev/full", "w") as full:
        r = subprocess.run([selfcald, opt], stdout=full, stderr=subprocess.PIPE, text=True, timeout=10)
    check(r.returncode == 1 and "cannot write to standard output" in r.stderr, f"{opt} > /dev/full: {r.returncode} {r.stderr}")
d = Daemon(selfcald, table)
try:
    rc, err = status(["--table", table, "--modbus-tcp", f"127.0.0.1:{d.port}"])
    check(rc == 1 and "cannot listen" in err, f"port taken: {rc} {err}")
finally:
    d.stop()
# 4. --syslog: RFC 3164 datagrams (facility daemon) to the syslog socket.
log_path = os.path.join(work, "syslog.sock")
if os.path.exists(log_path):
    os.unlink(log_path)
ls = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
ls.bind(log_path)
ls.settimeout(5)
p = subprocess.Popen([selfcald, "--table", table, "--modbus-tcp", "127.0.0.1:0", "--syslog",
                      "--syslog-socket", log_path], stderr=subprocess.PIPE, text=True)
try:
    lines = []
    while not any("ready" in m for m in lines):
        lines.append(ls.recv(2048).decode())
    check(all(m.startswith("<") and f"selfcald[{p.pid}]: " in m for m in lines), f"{lines}")
    check(lines[0].startswith("<29>"), f"notice in facility daemon is <29>: {lines[0]}")
    p.send_signal(signal.SIGTERM)
    check(p.wait(5) == 0, "exit status with --syslog")
    check(p.stderr.read() == "", "logged to stderr despite --syslog")
    # a failure to start goes to syslog and, for whoever started it, to stderr too
    rc, err = status(["--table", os.path.join(work, "missing.lut"), "--modbus-tcp",
                      "127.0.0.1:0", "--syslog", "--syslog-socket", log_path])
    check(rc == 2 and err.count("missing.lut") == 1, f"start failure with --syslog: {rc} {err}")
    got = ls.recv(2048).decode()
    while "missing.lut" not in got:
        got = ls.recv(2048).decode()
    check(got.startswith("<27>"), f"an error in facility daemon is <27>: {got}")
finally:
    if p.poll() is None:
        p.kill()
    ls.close()
print("daemon process (notify, signals, exit statuses, config): ok")
