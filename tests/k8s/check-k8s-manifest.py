#!/usr/bin/env python3
"""ctest K8sIndexedJob.*: render the per-index command of samples/k8s/animate-job.yaml (the
container command with its $(VAR) env references expanded and JOB_COMPLETION_INDEX set, as
Kubernetes does) and run it next to samples/slurm/animate.sbatch with the same array index
(SLURM_ARRAY_TASK_ID/COUNT); both must take the same frames and write the same bytes.
No cluster needed. Usage: check-k8s-manifest.py SPLATWARP_BINARY SOURCE_DIR"""
import filecmp, json, os, re, subprocess, sys, tempfile

binary, src = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
yaml = open(os.path.join(src, "samples/k8s/animate-job.yaml")).read()
completions = int(re.search(r"^\s*completions:\s*(\d+)", yaml, re.M).group(1))
assert re.search(r"^\s*completionMode:\s*Indexed", yaml, re.M), "the Job must be an Indexed Job"
env = dict(re.findall(r"-\s*\{name:\s*(\w+),\s*value:\s*\"?([^\"}]*)\"?\}", yaml))
command = json.loads(re.search(r"^\s*command:\s*(\[.*\])\s*$", yaml, re.M).group(1))
assert command[command.index("--shard-count") + 1] == str(completions), "--shard-count must equal completions"

with tempfile.TemporaryDirectory() as t:
    model, spec = os.path.join(t, "stripes.ply"), os.path.join(t, "bend-6.json")
    subprocess.run([binary, "-q", "sample", "stripes", "--count", "1500", "-o", model], check=True)
    with open(spec, "w") as f:
        f.write(open(os.path.join(src, "samples/specs/bend-24.json")).read().replace('"frames": 24', '"frames": 6'))
    extra = ["--stage1-only", "--nodes", "32"]  # Stage I only: the shard split is what is checked
    env.update(MODEL=model, SPEC=spec, OUTDIR=os.path.join(t, "k8s"), THREADS="1")
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("SLURM_", "JOB_COMPLETION"))}
    for i in range(completions):
        k8s = [re.sub(r"\$\((\w+)\)", lambda m: env[m.group(1)], w) for w in command]
        k8s = [binary if w == "splatwarp" else w for w in k8s] + extra
        slurm = ["bash", os.path.join(src, "samples/slurm/animate.sbatch"), model, spec, os.path.join(t, "slurm")] + extra
        print("index", i, "k8s:", " ".join(k8s))
        print("index", i, "slurm:", " ".join(slurm))
        subprocess.run(k8s, check=True, env=dict(clean, JOB_COMPLETION_INDEX=str(i)), stdout=subprocess.DEVNULL)
        subprocess.run(slurm, check=True, stdout=subprocess.DEVNULL,
                       env=dict(clean, SPLATWARP=binary, SLURM_ARRAY_TASK_ID=str(i), SLURM_ARRAY_TASK_MIN="0",
                                SLURM_ARRAY_TASK_COUNT=str(completions), SLURM_CPUS_PER_TASK="1"))
        mk = json.load(open(os.path.join(t, "k8s", f"manifest.shard-{i}.json")))
        ms = json.load(open(os.path.join(t, "slurm", f"manifest.shard-{i}.json")))
        assert mk["shard"]["source"] == "JOB_COMPLETION_INDEX" and ms["shard"]["source"] == "SLURM_ARRAY_TASK_ID"
        fk, fs = [e["frame"] for e in mk["entries"]], [e["frame"] for e in ms["entries"]]
        assert fk == fs == [f for f in range(6) if f % completions == i], (i, fk, fs)
        for e in mk["entries"]:
            for f in e["files"]:
                assert filecmp.cmp(os.path.join(t, "k8s", f["path"]), os.path.join(t, "slurm", f["path"]), shallow=False), f
print(f"PASS: {completions} indices of the Indexed Job take the frames of the Slurm array tasks, same bytes")
