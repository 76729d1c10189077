#!/usr/bin/env python3
"""selfcal_drive.py — the headless driver of selfcal_sim.ini, run by LinuxCNC as its DISPLAY
(`linuxcnc selfcal_sim.ini`; LinuxCNC starts it with `-ini FILE` once task and motion run, and
shuts the machine down when it exits). With the `linuxcnc` and `hal` Python modules of
LinuxCNC (Debian: linuxcnc-uspace), it:

1. records every servo period with halsampler (the sampler of selfcal_sim.hal: the sample's
   number, then the commanded machine position, the correction in um, the following error in nm,
   the applied fraction, the stage, the status);
2. puts the simulated stage where SELFCAL_POWERUP_MM says it stood at power-up ("x,y" mm,
   default "0,0"), resets the E-stop, turns the machine on, homes all joints (home switches);
3. waits for the correction to ramp in, moves to SELFCAL_FRAME_MM (default "5,-3") and reads where
   the stage is there (the frame: the same after every power-up, within the home switch's
   latch resolution);
4. runs the G-code program SELFCAL_PROGRAM (default selfcal_sim.ngc; "none": no program);
5. writes everything to SELFCAL_DRIVE_OUT (default selfcal_drive.json) and the samples to
   SELFCAL_DRIVE_OUT with .samples instead of .json; exits 0, or 1 with the reason in "error".
"""
import json
import os
import subprocess
import sys
import time

import hal
import linuxcnc

out_path = os.path.abspath(os.environ.get("SELFCAL_DRIVE_OUT", "selfcal_drive.json"))
samples_path = out_path[:-5] + ".samples" if out_path.endswith(".json") else out_path + ".samples"
powerup = [float(v) for v in os.environ.get("SELFCAL_POWERUP_MM", "0,0").split(",")]
frame_at = [float(v) for v in os.environ.get("SELFCAL_FRAME_MM", "5,-3").split(",")]
program = os.environ.get("SELFCAL_PROGRAM", "selfcal_sim.ngc")
result = {"powerup_mm": powerup, "frame_at_mm": frame_at, "events": []}

c = linuxcnc.command()
s = linuxcnc.stat()
err = linuxcnc.error_channel()
comp = hal.component("selfcal-drive")  # to set and read pins from here
comp.ready()


def event(what):
    result["events"].append([round(time.time(), 3), what])


def pins(*names):
    return {n: hal.get_value(n) for n in names}


def wait(cond, timeout_s, what):
    """Polls LinuxCNC's status until cond() holds; fails on an operator error or a timeout."""
    end = time.time() + timeout_s
    while time.time() < end:
        s.poll()
        e = err.poll()
        if e and e[0] in (linuxcnc.OPERATOR_ERROR, linuxcnc.NML_ERROR):
            raise RuntimeError(f"{what}: LinuxCNC error: {e[1]}")
        if cond():
            return
        time.sleep(0.01)
    raise RuntimeError(f"{what}: not after {timeout_s} s")


def ensure_mode(m):
    s.poll()
    if s.task_mode != m:
        c.mode(m)
        c.wait_complete()


def at_rest(timeout_s=30):
    wait(lambda: s.inpos and s.current_vel == 0, timeout_s, "in position")


# -t: each line starts with the sample's number, so that samples lost (the FIFO full because the
# machine was too busy to read it) show as gaps
sampler = subprocess.Popen(["halsampler", "-t"], stdout=open(samples_path, "w"))
try:
    hal.set_p("sampler.0.enable", "1")
    hal.set_p("x-stage.offset", repr(powerup[0]))
    hal.set_p("y-stage.offset", repr(powerup[1]))
    time.sleep(0.05)
    result["before_homing"] = pins("selfcal-xy.0.fraction", "selfcal-xy.0.status",
                                   "x-stage.out", "y-stage.out")
    c.state(linuxcnc.STATE_ESTOP_RESET)
    c.state(linuxcnc.STATE_ON)
    wait(lambda: s.task_state == linuxcnc.STATE_ON, 20, "machine on")
    ensure_mode(linuxcnc.MODE_MANUAL)
    c.teleop_enable(0)
    c.wait_complete()
    event("homing")
    c.home(-1)
    wait(lambda: all(s.homed[k] for k in range(2)), 120, "homing")
    event("homed")
    result["homed"] = pins("joint.0.motor-offset", "joint.1.motor-offset",
                           "selfcal-xy.0.fraction", "x-home-sw.in0", "y-home-sw.in0")
    # the correction ramps in once everything is homed
    end = time.time() + 10
    while hal.get_value("selfcal-xy.0.fraction") < 1.0 and time.time() < end:
        time.sleep(0.01)
    event("ramped in")
    ensure_mode(linuxcnc.MODE_MDI)
    c.mdi(f"G0 X{frame_at[0]:.6f} Y{frame_at[1]:.6f}")
    c.wait_complete(30)
    at_rest()
    time.sleep(0.1)
    result["frame"] = pins("x-stage.out", "y-stage.out", "joint.0.f-error", "joint.1.f-error",
                           "joint.0.pos-fb", "joint.1.pos-fb", "selfcal-xy.0.x-in",
                           "selfcal-xy.0.y-in", "selfcal-xy.0.x-out", "selfcal-xy.0.y-out",
                           "selfcal-xy.0.fraction", "selfcal-xy.0.status")
    event("frame")
    if program != "none":
        ensure_mode(linuxcnc.MODE_AUTO)
        c.program_open(os.path.abspath(program))
        c.auto(linuxcnc.AUTO_RUN, 0)
        wait(lambda: s.interp_state != linuxcnc.INTERP_IDLE, 10, "program start")
        event("program")
        wait(lambda: s.interp_state == linuxcnc.INTERP_IDLE, 300, "program end")
        at_rest()
        time.sleep(0.1)
        event("program done")
        result["end"] = pins("joint.0.f-error", "joint.1.f-error", "selfcal-xy.0.status",
                             "sampler.0.overruns")
    # unhoming takes the correction out again (motion.is-all-homed goes FALSE)
    ensure_mode(linuxcnc.MODE_MANUAL)
    c.teleop_enable(0)
    c.wait_complete()
    c.unhome(-1)
    c.wait_complete()
    time.sleep(0.3)
    result["unhomed"] = pins("selfcal-xy.0.fraction", "selfcal-xy.0.status")
    event("unhomed")
    result["ok"] = True
except Exception as e:  # noqa: BLE001 - everything goes into the result file
    result["ok"] = False
    result["error"] = str(e)
finally:
    try:
        hal.set_p("sampler.0.enable", "0")
        time.sleep(0.2)
    except Exception:  # noqa: BLE001
        pass
    sampler.terminate()
    sampler.wait(10)
    with open(out_path + ".tmp", "w") as f:
        json.dump(result, f, indent=1)
    os.replace(out_path + ".tmp", out_path)
    try:
        c.state(linuxcnc.STATE_ESTOP)
    except Exception:  # noqa: BLE001
        pass
sys.exit(0 if result["ok"] else 1)
