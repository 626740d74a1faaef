#!/usr/bin/env bash
# Runs the benchmarks and writes their CSVs to build/bench/ (summarised by hand in BENCHMARKS.md).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh --target bench_foundation bench_dynamics bench_registration bench_registration_real bench_inpainting bench_appearance bench_appearance_real bench_gl_compose bench_rehearsal bench_rehearsal_view bench_replay bench_kernels bench_start bench_operative
mkdir -p build/bench
build/tests/bench_foundation build/bench/bench_foundation.csv
build/tests/bench_dynamics build/bench
build/tests/bench_registration build/bench --repeat 3
build/tests/bench_registration_real build/bench --fractions 1,0.7,0.5
build/tests/bench_inpainting build/bench
build/tests/bench_appearance build/bench
build/tests/bench_appearance_real build/bench --repeat 3
xvfb-run -a -s "-screen 0 1600x1000x24" build/tests/bench_gl_compose build/bench
build/tests/bench_rehearsal build/bench
build/tests/bench_start build/bench
build/tests/bench_replay build/bench
build/tests/bench_kernels build/bench
xvfb-run -a -s "-screen 0 2560x1440x24" build/tests/bench_rehearsal_view build/bench --software
xvfb-run -a -s "-screen 0 2560x1440x24" build/tests/bench_rehearsal_view build/bench --opengl
xvfb-run -a -s "-screen 0 2560x1440x24" build/tests/bench_rehearsal_view build/bench
build/tests/bench_operative build/bench --repeat 3
# The GUI's damping (app::bodySetup: alpha 0.1 1/s, beta 0.02 s; the case's scene declares 1 and 0), the GUI's variant.
build/tests/bench_operative build/bench/gui-damping --repeat 3 --damping 0.1,0.02 --only "=chord, async, 0.05 mm"
# The window's variant as the window runs it (paced at real time, its estimate every 10th step), and issue 61's tear:
# the grasper alone pulling past the recommended 15 % and let go 0.2 s after the first tear.
build/tests/bench_operative build/bench/window-paced --repeat 3 --damping 0.1,0.02 --estimate-every 10 --paced --only "=chord, async, 0.05 mm"
build/tests/bench_operative build/bench/tear-once --repeat 3 --damping 0.1,0.02 --estimate-every 10 --paced --tear-once --only "=chord, async, 0.05 mm"
build/tests/bench_operative build/bench/tear-once-3k --repeat 3 --tets 4000 --damping 0.1,0.02 --estimate-every 10 --paced --tear-once --only "=chord, async, 0.05 mm"
# Issue 64's sizes: the patient liver at 15,899 elements and BodyParts3D's at 17,051, the window's variant, damping and
# estimate (one run each: about 2 minutes apiece).
build/tests/bench_operative build/bench/patient-16k --repeat 1 --tets 17000 --damping 0.1,0.02 --estimate-every 10 --only "=chord, async, 0.05 mm"
build/tests/bench_operative build/bench/bodyparts3d-17k --repeat 1 --organ bodyparts3d --tets 17000 --damping 0.1,0.02 --estimate-every 10 --only "=chord, async, 0.05 mm"
