#!/usr/bin/env bash
# The main job, end to end on the virtual KR C4: excite -> capture -> fit -> report/diagnose.
# Usage: scripts/demo.sh OUTDIR   (run by `make demo`, which installs kukaid first)
set -euo pipefail
out=${1:-reports/demo}
mkdir -p "$out"
echo "== kukaid demo: writing into $out"
# -- excitation trajectories (and KRL programs a KR C4 can run)
for kind in friction inertia presliding validation; do
    kukaid excite "$kind" -o "$out/$kind.json" --krl "$out/krl" --force
done
# -- capture on the virtual KR C4
seed=1
for kind in friction inertia presliding validation; do
    kukaid capture "$out/$kind.json" -o "$out/$kind.h5" --seed "$seed" --force
    seed=$((seed + 1))
done
# -- capture through KUKAVARPROXY: `serve-sim` is the virtual KR C4 on the network, `capture --backend kvp`
#    records it with the KRL ring-buffer logger's exact 12 ms samples (real time; KUKAID_DEMO_KVP=0 skips)
if [ "${KUKAID_DEMO_KVP:-1}" != 0 ]; then
    kukaid krl-logger --axis 3 -o "$out/krl" --force
    dur=$(python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['duration'])" "$out/inertia.json")
    rm -f "$out/serve-sim.log"  # the port is read from this run's log, not an earlier one's
    kukaid serve-sim --port 0 --trajectory "$out/inertia.json" --seed 7 --duration "$(python3 -c "print($dur + 4)")" \
        --truth "$out/inertia_kvp_truth.h5" --force 2> "$out/serve-sim.log" &
    sim_pid=$!
    for _ in $(seq 200); do grep -qs listening "$out/serve-sim.log" && break; sleep 0.1; done
    port=$(sed -n 's/.*listening on [0-9.]*:\([0-9]*\).*/\1/p' "$out/serve-sim.log")
    kukaid capture "$out/inertia.json" -o "$out/inertia_kvp.h5" --backend kvp --port "$port" --axis 3 --mode ring \
        --duration "$dur" --force
    wait "$sim_pid"
fi
# -- identification
kukaid fit --friction "$out/friction.h5" --inertia "$out/inertia.h5" --presliding "$out/presliding.h5" \
    -o "$out/params.json"
# -- report: the paper's figures and tables of the fit (PDF)
kukaid report --params "$out/params.json" --friction "$out/friction.h5" --inertia "$out/inertia.h5" \
    --presliding "$out/presliding.h5" --log "$out/validation.h5" -o "$out/report.pdf"
# -- diagnosis
#    of the demo's own fit (clean data: expect "no effect is missing"), then of logs with a hidden
#    gear ripple (capture --effect): the diagnosis names it, refits, and the gap closes to the noise
kukaid diagnose --params "$out/params.json" --log "$out/friction.h5" --log "$out/inertia.h5" \
    --report "$out/diagnose.pdf" | tee "$out/diagnose.txt"
for kind in friction inertia; do
    kukaid capture "$out/$kind.json" -o "$out/${kind}_ripple.h5" --seed 11 --effect position_ripple=1.5 --force
done
kukaid fit --friction "$out/friction_ripple.h5" --inertia "$out/inertia_ripple.h5" -o "$out/params_ripple.json"
kukaid diagnose --params "$out/params_ripple.json" --log "$out/friction_ripple.h5" --log "$out/inertia_ripple.h5" \
    --report "$out/diagnose_ripple.pdf" -o "$out/params_ripple_diagnosed.json" | tee "$out/diagnose_ripple.txt"
# -- sensorless admittance control on the virtual KR C4 (a simulated hand drags the axis), and the
#    KRL follower program a real KR C4 would run for `run-admittance --backend kvp`
kukaid krl-follower --axis 3 --q-min 0 --q-max 60 -o "$out/krl" --force
kukaid run-admittance --params "$out/params.json" --damping adaptive --operator pull --seed 1 --duration 8 \
    -o "$out/admittance.h5" --report "$out/admittance.pdf" --force | tee "$out/admittance.txt"
echo "== demo done: $(ls "$out" | tr '\n' ' ')"
