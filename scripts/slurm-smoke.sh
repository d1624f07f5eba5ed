#!/bin/bash
# Shards on a real scheduler: starts a one-node Slurm on this machine (Debian's slurm-wlm with
# munge, installed if missing: needs root), submits `stairbench regress smoke` as an array of 4
# shards (each reads its shard from SLURM_ARRAY_TASK_ID/_MIN/_COUNT, as Slurm sets them), waits,
# merges the shards' results, and checks them case for case against a local run of the same
# suite (verdict and simulated time). Everything lives in a temporary folder; the daemons are
# stopped on exit. Usage: scripts/slurm-smoke.sh [BIN [LOCAL]] (BIN defaults to
# ./target/release/stairbench). LOCAL, if given, is the results.jsonl of a local `regress smoke`
# run by this same binary (the one `make test` leaves), used instead of running the suite again
# here; it is ignored, and the suite run, when it is older than the binary.
# `make test-slurm` runs it; `.ci/run` calls that.
set -euo pipefail

BIN=$(realpath "${1:-./target/release/stairbench}")
LOCAL=${2:-}
SHARDS=4
[ -x "$BIN" ] || { echo "slurm-smoke: no stairbench binary at $BIN (make build first)" >&2; exit 2; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    [ "$(id -u)" = 0 ] || { echo "slurm-smoke: slurm-wlm and munge are not installed, and installing them needs root" >&2; exit 2; }
    echo "slurm-smoke: installing slurm-wlm and munge (Debian packages)"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q slurm-wlm munge >/dev/null ||
        { apt-get update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q slurm-wlm munge >/dev/null; }
fi

D=$(mktemp -d /tmp/stairbench-slurm.XXXXXX)
cleanup() {
    [ -f "$D/slurmd.pid" ] && kill "$(cat "$D/slurmd.pid")" 2>/dev/null || true
    [ -f "$D/slurmctld.pid" ] && kill "$(cat "$D/slurmctld.pid")" 2>/dev/null || true
    [ -f "$D/munged.pid" ] && kill "$(cat "$D/munged.pid")" 2>/dev/null || true
    sleep 1
    if [ "${KEEP:-0}" = 1 ]; then echo "slurm-smoke: kept $D"; else rm -rf "$D"; fi
}
trap cleanup EXIT
mkdir -p "$D/state" "$D/spool" "$D/out" "$D/munge"
chmod 700 "$D/munge"

# munge, on its own key and socket.
dd if=/dev/urandom of="$D/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$D/munge/munge.key"
munged --force --key-file="$D/munge/munge.key" --socket="$D/munge/munge.sock" \
    --pid-file="$D/munged.pid" --log-file="$D/munged.log" --seed-file="$D/munge/seed"

# One node, this machine, with its cores; ports off the defaults.
HOST=$(hostname -s)
CPUS=$(nproc)
MEM_MB=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2 ))
cat > "$D/slurm.conf" <<EOF
ClusterName=stairbench
SlurmctldHost=$HOST
SlurmctldPort=16817
SlurmdPort=16818
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$D/munge/munge.sock
CredType=cred/munge
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/slurmctld.pid
SlurmdPidFile=$D/slurmd.pid
SlurmctldLogFile=$D/slurmctld.log
SlurmdLogFile=$D/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
NodeName=$HOST CPUs=$CPUS RealMemory=$MEM_MB State=UNKNOWN
PartitionName=local Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$D/slurm.conf"
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 60); do
    sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
    sleep 1
done
sinfo -h -o %t | grep -qE '^(idle|mix|alloc)' || {
    echo "slurm-smoke: the node did not come up; the logs:" >&2
    tail -20 "$D/slurmctld.log" "$D/slurmd.log" >&2
    exit 1
}
echo "slurm-smoke: one-node Slurm up ($HOST, $CPUS cores)"

# The array: each task runs its shard, one climb at a time.
cat > "$D/shard.sh" <<EOF
#!/bin/bash
exec "$BIN" regress smoke --out "$D/out/shard-\$SLURM_ARRAY_TASK_ID" --jobs 1 -q
EOF
chmod +x "$D/shard.sh"
sbatch --wait --array=1-$SHARDS --cpus-per-task=1 --output="$D/out/shard-%a.log" "$D/shard.sh" ||
    echo "slurm-smoke: some shards failed (a failing case fails its shard); merging what came back"
"$BIN" regress merge "$D"/out/shard-*/results.jsonl --out "$D/merged.jsonl" --junit "$D/merged.xml" || true
[ -s "$D/merged.jsonl" ] || { echo "slurm-smoke: no merged results" >&2; exit 1; }

# The same suite run here (or the given local run of this binary), compared case for case.
if [ -n "$LOCAL" ] && [ -s "$LOCAL" ] && [ "$LOCAL" -nt "$BIN" ]; then
    echo "slurm-smoke: comparing with the local run in $LOCAL"
    mkdir -p "$D/local" && cp "$LOCAL" "$D/local/results.jsonl"
else
    "$BIN" regress smoke --out "$D/local" -q || true
fi
python3 - "$D/merged.jsonl" "$D/local/results.jsonl" "$SHARDS" <<'EOF'
import json, sys
def load(path):
    out = {}
    for line in open(path):
        r = json.loads(line)
        out[(r["id"], r.get("seed_index", 0))] = r
    return out
slurm, local, shards = load(sys.argv[1]), load(sys.argv[2]), int(sys.argv[3])
bad = [k for k in local if k not in slurm] + [k for k in slurm if k not in local]
for k in local.keys() & slurm.keys():
    a, b = local[k], slurm[k]
    if a["verdict"] != b["verdict"] or abs(a["sim_s"] - b["sim_s"]) > 1e-9:
        bad.append((k, a["verdict"], b["verdict"], a["sim_s"], b["sim_s"]))
passed = sum(r["pass"] for r in slurm.values())
print(f"slurm-smoke: {len(slurm)} runs from {shards} Slurm shards, {passed} passed; "
      f"{len(local)} runs here; {len(bad)} differ")
for b in bad:
    print("  differs:", b)
sys.exit(1 if bad or passed < len(slurm) else 0)
EOF
