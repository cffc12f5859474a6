#!/usr/bin/python3
"""ctest workflows/slurm: starts a single-node Slurm cluster on this machine (Debian's slurm-wlm
and munge, configured here in a temp folder: its own munge key and socket, slurm.conf with
free ports, state and spool folders; no systemd), runs workflows/Snakefile through it with
--profile workflows/profiles/slurm on two tiny synthetic turntable captures (one broken), and
checks that both captures were run as Slurm jobs (one Slurm log per job, the jobs known to
Slurm by name), the good one gives a mesh, the broken one its error row, and the index lists
both. Skips (exit 77) with a message when the cluster cannot start: not root, slurm-wlm,
munge or snakemake missing, or the daemons do not come up.
Usage: slurm_test.py SOURCE_DIR BIN_DIR.
"""
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

SKIP = 77
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from collection_test import check, write_ellipsoid  # noqa: E402


def skip(msg):
    print(f"SKIP: {msg}")
    sys.exit(SKIP)


def free_port():
    with socket.socket() as s:
        s.bind(("", 0))
        return s.getsockname()[1]


def tail(path, n=15):
    try:
        return "".join(open(path, errors="replace").readlines()[-n:])
    except OSError:
        return "(no log)"


class Cluster:
    """munged + slurmctld + slurmd in `root`, stopped by stop() (their pids only)."""

    def __init__(self, root):
        self.root, self.procs = root, []
        self.host = socket.gethostname().split(".")[0]
        self.conf = os.path.join(root, "slurm.conf")
        self.sock = os.path.join(root, "munge", "munge.socket")

    def start(self):
        r = self.root
        for d in ("munge", "state", "spool", "log"):
            os.makedirs(os.path.join(r, d), mode=0o700)
        key = os.path.join(r, "munge", "munge.key")
        subprocess.run(["mungekey", "--create", "--keyfile", key], check=True,
                       capture_output=True)
        os.chmod(key, 0o600)
        self.procs.append(subprocess.Popen(
            ["munged", "--foreground", "--force", f"--socket={self.sock}", f"--key-file={key}",
             f"--pid-file={r}/munge/munged.pid", f"--log-file={r}/log/munged.log",
             f"--seed-file={r}/munge/munged.seed"],
            stdout=subprocess.DEVNULL, stderr=open(f"{r}/log/munged.err", "w")))
        for _ in range(50):
            if os.path.exists(self.sock):
                break
            time.sleep(0.1)
        else:
            return f"munged did not start: {tail(f'{r}/log/munged.err')}"
        cpus = os.cpu_count() or 1
        mem_mb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // (1 << 20)
        with open(self.conf, "w") as f:
            f.write(f"""ClusterName=rgbdtest
SlurmctldHost={self.host}
SlurmctldPort={free_port()}
SlurmdPort={free_port()}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={self.sock}
StateSaveLocation={r}/state
SlurmdSpoolDir={r}/spool
SlurmctldPidFile={r}/slurmctld.pid
SlurmdPidFile={r}/slurmd.pid
SlurmctldLogFile={r}/log/slurmctld.log
SlurmdLogFile={r}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SwitchType=switch/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
NodeName={self.host} CPUs={cpus} RealMemory={mem_mb // 2} State=UNKNOWN
PartitionName=debug Nodes={self.host} Default=YES MaxTime=INFINITE State=UP
""")
        env = self.env()
        self.procs.append(subprocess.Popen(["slurmctld", "-D", "-i", "-f", self.conf], env=env,
                                           stdout=subprocess.DEVNULL,
                                           stderr=open(f"{r}/log/slurmctld.err", "w")))
        time.sleep(1)
        self.procs.append(subprocess.Popen(["slurmd", "-D", "-f", self.conf], env=env,
                                           stdout=subprocess.DEVNULL,
                                           stderr=open(f"{r}/log/slurmd.err", "w")))
        for _ in range(60):
            out = subprocess.run(["sinfo", "-h", "-o", "%T"], env=env, capture_output=True,
                                 text=True)
            if out.returncode == 0 and out.stdout.strip() in ("idle", "mixed", "allocated"):
                return ""
            if any(p.poll() is not None for p in self.procs):
                break
            time.sleep(1)
        return ("the Slurm daemons did not come up:\nslurmctld: " +
                tail(f"{r}/log/slurmctld.log") + tail(f"{r}/log/slurmctld.err") +
                "\nslurmd: " + tail(f"{r}/log/slurmd.log") + tail(f"{r}/log/slurmd.err"))

    def env(self):
        e = dict(os.environ)
        e["SLURM_CONF"] = self.conf
        return e

    def stop(self):
        for p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in reversed(self.procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def main():
    src, bindir = sys.argv[1], sys.argv[2]
    if os.geteuid() != 0:
        skip("needs root to start slurmctld, slurmd and munged")
    for tool in ("slurmctld", "slurmd", "sbatch", "sinfo", "munged", "mungekey", "snakemake"):
        if shutil.which(tool) is None:
            skip(f"{tool} is not installed (Debian packages slurm-wlm, munge, snakemake)")
    tmp = tempfile.mkdtemp(prefix="rgbd-slurm-")
    cluster = Cluster(os.path.join(tmp, "cluster"))
    os.makedirs(cluster.root)
    try:
        why = cluster.start()
        if why:
            cluster.stop()
            skip(why)
        caps, results = os.path.join(tmp, "captures"), os.path.join(tmp, "results")
        os.makedirs(caps)
        mesh = os.path.join(tmp, "ellipsoid.off")
        write_ellipsoid(mesh)
        for name, seed in (("egg", 1), ("egg_broken", 2)):
            r = subprocess.run([os.path.join(bindir, "rgbd-synth"), mesh, "-o",
                                os.path.join(caps, name), "--rig", "turntable", "--stops", "8",
                                "--resolution-scale", "0.4", "--height-m", "0.16", "--up", "z",
                                "--seed", str(seed), "-q"], capture_output=True, text=True)
            check(r.returncode == 0, f"rgbd-synth {name} {r.stderr}")
        os.remove(os.path.join(caps, "egg_broken", "framesets.csv"))
        with open(os.path.join(caps, "egg_broken", "rig.json"), "w") as f:
            f.write("{\"sensors\": 3}\n")  # valid JSON, not a rig

        t0 = time.time()
        r = subprocess.run(
            ["snakemake", "-s", os.path.join(src, "workflows", "Snakefile"), "--profile",
             os.path.join(src, "workflows", "profiles", "slurm"), "--config",
             f"captures={caps}", f"results={results}", f"bin={bindir}", "threads=1",
             "mem_mb=500", "runtime_min=10"],
            cwd=tmp, env=cluster.env(), capture_output=True, text=True, timeout=900)
        check(r.returncode == 0, f"workflow through Slurm exits 0 ({time.time() - t0:.0f} s)" +
              ("" if r.returncode == 0 else "\n" + (r.stdout + r.stderr)[-1500:]))
        submitted = re.findall(r"Submitted job \d+ with external jobid '(\d+)'",
                               r.stdout + r.stderr)
        check(len(submitted) == 2, f"two Slurm jobs submitted ({submitted})")
        logs = [f for f in os.listdir(os.path.join(results, ".snakemake"))
                if f.startswith("slurm-") and f.endswith(".log")]
        check(sorted(logs) == sorted(f"slurm-{j}.log" for j in submitted),
              f"one Slurm log per job ({logs})")
        check(os.path.getsize(os.path.join(results, "egg", "mesh.ply")) > 1000, "egg: mesh.ply")
        st = json.load(open(os.path.join(results, "egg", "status.json")))
        check(st["status"] == "ok", "egg: status ok")
        st = json.load(open(os.path.join(results, "egg_broken", "status.json")))
        check(st["status"] == "failed" and "rig.json" in st["error"],
              f"egg_broken: failed, error names rig.json ({st['error'][:100]})")
        page = open(os.path.join(results, "index.html")).read()
        check(page.count('<tr class="ok">') == 1 and page.count('<tr class="failed">') == 1,
              "index: one ok row, one failed row")
    finally:
        cluster.stop()
        shutil.rmtree(tmp, ignore_errors=True)
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
