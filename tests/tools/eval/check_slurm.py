#!/usr/bin/python3
"""A sharded sfrt eval and sfrt run on a real Slurm, as examples/slurm/ runs them, merge into the
local runs.

Starts a single-node Slurm (Debian's slurm-wlm 22.05: slurmctld and slurmd in the foreground,
AuthType=auth/none and CredType=cred/none, so no munge; ports chosen free on loopback; state, spool
and logs in a temporary folder), submits examples/slurm/submit.sh's 3-task array over a synthesised
dataset and its merge job (--dependency=afterok), waits for both, and checks that the merged --json
is the local single run's byte for byte and that every array task saw its own index; then the same
with JOB=run (a replay: the merged summary has the local run's counts and the shards wrote its
flow files, byte for byte). Stops both
daemons by PID (SIGTERM), also on failure, and prints their logs when something fails.

usage: check_slurm.py --sfrt BIN --model M --examples DIR --work DIR
"""
import argparse
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

CONF = """ClusterName=sfrtci
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={ctld_port}
SlurmdPort={slurmd_port}
SlurmUser=root
SlurmdUser=root
AuthType=auth/none
CredType=cred/none
StateSaveLocation={t}/state
SlurmdSpoolDir={t}/spool
SlurmctldPidFile={t}/run/slurmctld.pid
SlurmdPidFile={t}/run/slurmd.pid
SlurmctldLogFile={t}/log/slurmctld.log
SlurmdLogFile={t}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
DependencyParameters=kill_invalid_depend
PropagateResourceLimits=NONE
NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN
PartitionName=ci Nodes={host} Default=YES MaxTime=INFINITE State=UP
"""


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(cmd, env=None):
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise RuntimeError("exit %d: %s\n%s%s" % (p.returncode, " ".join(cmd), p.stdout, p.stderr))
    return p.stdout


def wait_for(what, check, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if check():
            return
        time.sleep(0.5)
    raise RuntimeError("timed out after %d s waiting for %s" % (seconds, what))


class Slurm:
    """A single-node cluster in folder `t`; stop() ends both daemons."""

    def __init__(self, t):
        self.t = t
        self.host = socket.gethostname().split(".")[0]
        for sub in ("etc", "state", "spool", "log", "run"):
            os.makedirs(os.path.join(t, sub), exist_ok=True)
        conf = os.path.join(t, "etc", "slurm.conf")
        with open(conf, "w") as f:
            f.write(CONF.format(host=self.host, t=t, ctld_port=free_port(),
                                slurmd_port=free_port(), cpus=os.cpu_count()))
        # slurmd initialises a cgroup plugin whatever the config says; cgroup/v1's init does
        # nothing, so it starts without systemd or a writable cgroup tree.
        with open(os.path.join(t, "etc", "cgroup.conf"), "w") as f:
            f.write("CgroupPlugin=cgroup/v1\n")
        self.env = dict(os.environ, SLURM_CONF=conf)
        self.daemons = []
        for daemon in ("slurmctld", "slurmd"):
            log = open(os.path.join(t, "log", daemon + ".stderr"), "w")
            self.daemons.append(subprocess.Popen([daemon, "-D", "-f", conf], env=self.env,
                                                 stdout=log, stderr=subprocess.STDOUT))

    def idle(self):
        for d in self.daemons:
            if d.poll() is not None:
                raise RuntimeError("%s exited with %d" % (d.args[0], d.returncode))
        p = subprocess.run(["sinfo", "-h", "-n", self.host, "-o", "%T"], capture_output=True,
                           text=True, env=self.env)
        return p.returncode == 0 and p.stdout.strip() == "idle"

    def finished(self, jobs):
        return run(["squeue", "-h", "-j", ",".join(jobs)], env=self.env).strip() == ""

    def states(self, job):
        return run(["squeue", "-h", "-t", "all", "-j", job, "-o", "%T"], env=self.env).split()

    def stop(self):
        for d in reversed(self.daemons):
            if d.poll() is None:
                d.send_signal(signal.SIGTERM)
        for d in self.daemons:
            try:
                d.wait(timeout=30)
            except subprocess.TimeoutExpired:
                d.kill()
                d.wait()

    def logs(self):
        text = ""
        for name in sorted(os.listdir(os.path.join(self.t, "log"))):
            with open(os.path.join(self.t, "log", name), errors="replace") as f:
                text += "--- %s\n%s" % (name, f.read()[-4000:])
        return text


def flow_files(folders):
    """name -> bytes of the .pfm flow files in `folders`."""
    out = {}
    for folder in folders:
        for name in os.listdir(folder):
            if name.endswith(".pfm"):
                with open(os.path.join(folder, name), "rb") as f:
                    out[name] = f.read()
    return out


def check_replay(a, slurm, data, failed):
    """JOB=run: the 3 array tasks replay the dataset into replay/shard-I-of-3/ and the merge job
    writes the summary of the local single run: the same frames, windows, source line and last
    window; the shards' flow files are the single run's, byte for byte."""
    model = os.path.abspath(a.model)
    local = os.path.join(a.work, "replay_single")
    run([a.sfrt, "run", "--model", model, "--replay", data, "--out", local, "--progress", "off"])
    out = os.path.join(a.work, "out_run")
    start = time.monotonic()
    env = dict(slurm.env, SFRT=os.path.abspath(a.sfrt), MODEL=model, DATASET=data, OUT=out,
               SHARDS="3", JOB="run")
    jobs = run(["bash", os.path.join(a.examples, "submit.sh")], env=env).split()
    wait_for("the replay array and its merge", lambda: slurm.finished([jobs[1], jobs[3]]), 240)
    states = slurm.states(jobs[1]) + slurm.states(jobs[3])
    if states != ["COMPLETED"] * 4:
        failed.append("replay job states %s; expected 3 completed tasks and the merge" % states)
        return
    with open(os.path.join(local, "summary.json")) as f:
        single = json.load(f)
    with open(os.path.join(out, "merged.json")) as f:
        merged = json.load(f)
    for key in ("frames", "windows", "drops", "preprocess", "bad_frames"):
        if single[key] != merged[key]:
            failed.append("replay: merged %s %s, the local run's %s" % (key, merged[key],
                                                                      single[key]))
    for key in ("description", "images_decoded", "windows_expected"):
        if single["source"][key] != merged["source"][key]:
            failed.append("replay: merged source.%s differs from the local run's" % key)
    if single["outputs"]["last"] != merged["outputs"]["last"]:
        failed.append("replay: merged outputs.last %s" % merged["outputs"]["last"])
    shards = [os.path.join(out, "replay", "shard-%d-of-3" % i) for i in range(3)]
    if flow_files([local]) != flow_files(shards):
        failed.append("replay: the shards' flow files are not the local run's")
    print("slurm: replay array of 3 and merge done in %.1f s, %d windows as the local run's" % (
        time.monotonic() - start, merged["frames"]["written"]))


def main():
    ap = argparse.ArgumentParser()
    for flag in ("--sfrt", "--model", "--examples", "--work"):
        ap.add_argument(flag, required=True)
    a = ap.parse_args()
    for tool in ("slurmctld", "slurmd", "sbatch", "squeue", "sinfo"):
        if shutil.which(tool) is None:
            print("FAIL: %s is not installed (tools/install-deps.sh installs slurm-wlm)" % tool)
            sys.exit(1)
    if os.geteuid() != 0:
        print("FAIL: slurmd runs jobs as their users and needs root; run the suite as root")
        sys.exit(1)
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    data = os.path.join(a.work, "data")
    run([a.sfrt, "synth", "--out", data, "--scene", "robot", "--seed", "21", "--sequences", "4",
         "--frames", "3", "--size", "96x128", "--focal", "90", "--baseline", "0.12",
         "--objects", "3"])
    single = os.path.join(a.work, "single.json")
    run([a.sfrt, "eval", "--model", os.path.abspath(a.model), "--dataset", data, "--json", single,
         "--quiet"])

    # slurmstepd's sockets live in the spool folder: keep its path short.
    t = tempfile.mkdtemp(prefix="sfrt-slurm-", dir="/tmp")
    out = os.path.join(a.work, "out")
    slurm = Slurm(t)
    failed = []
    try:
        start = time.monotonic()
        wait_for("the node to be idle", slurm.idle, 60)
        up = time.monotonic() - start
        env = dict(slurm.env, SFRT=os.path.abspath(a.sfrt), MODEL=os.path.abspath(a.model),
                   DATASET=data, OUT=out, SHARDS="3")
        jobs = run(["bash", os.path.join(a.examples, "submit.sh")], env=env).split()
        shards, merge = jobs[1], jobs[3]
        wait_for("the array and the merge", lambda: slurm.finished([shards, merge]), 240)
        done = time.monotonic() - start - up
        states = slurm.states(shards) + slurm.states(merge)
        if states != ["COMPLETED"] * 4:
            failed.append("job states %s; expected 3 completed array tasks and the merge" % states)
        with open(single, "rb") as f, open(os.path.join(out, "merged.json"), "rb") as g:
            if f.read() != g.read():
                failed.append("the merged --json differs from the local single run's")
        for i in range(3):
            with open(os.path.join(out, "shard_%d.json" % i)) as f:
                shard = json.load(f)["shard"]
            if (shard["index"], shard["count"]) != (i, 3):
                failed.append("shard_%d.json says shard %s/%s" % (i, shard["index"],
                                                                shard["count"]))
        print("slurm: node idle after %.1f s; array of 3 and merge done in %.1f s" % (up, done))
        check_replay(a, slurm, data, failed)
    except (RuntimeError, OSError, ValueError, IndexError) as e:
        failed.append(str(e))
    finally:
        slurm.stop()
    if failed:
        for f in failed:
            print("FAIL: " + f)
        print(slurm.logs())
        for name in sorted(os.listdir(out)) if os.path.isdir(out) else []:
            if name.endswith(".out"):
                with open(os.path.join(out, name), errors="replace") as f:
                    print("--- %s\n%s" % (name, f.read()[-2000:]))
        sys.exit(1)
    shutil.rmtree(t, ignore_errors=True)
    print("PASS: the merged --json of 3 Slurm array tasks is the single run's, byte for byte; "
          "the merged replay is the single run's")


if __name__ == "__main__":
    main()
