# Front door of the project. `make demo` and `make test` work on a fresh Debian machine: they set up
# what is missing (tools/setup.sh), build, and run everything that uses multicast inside the project's
# own network namespace (tools/netns).
SHELL      := /bin/bash
ROOT       := $(abspath .)
VENV       := $(ROOT)/.venv
PY         := $(VENV)/bin/python
BUILD      := $(ROOT)/build
# Deferred (=): the venv may only exist once `setup` has run.
SITE        = $(shell ls -d $(VENV)/lib/python3*/site-packages 2>/dev/null | head -1)
NETNS      := $(ROOT)/tools/netns
JOBS       ?= 2
export PYTHONPATH := $(ROOT):$(BUILD)/gen/python
export PATH       := $(VENV)/bin:$(PATH)
export T1_BUILD   := $(BUILD)
export MUJOCO_GL  ?= osmesa
export PYOPENGL_PLATFORM ?= osmesa

# Simulator arguments for `make sim`, e.g. make sim SIM_ARGS="--spawn fallen:3 --clock lockstep"
SIM_ARGS ?= --scenario flat --spawn standing --clock realtime

.PHONY: all setup build test test-fast lint sim spy spy-dds demo teleop bench bench-env bench-train bench-soak clean replay plot-log view-log

# VIEW=rerun on demo, teleop and sim: a live Rerun view of the run (tools/rerun_live; README: Runs in Rerun)
VIEW ?=
IN_NETNS = $(if $(filter rerun,$(VIEW)),$(ROOT)/tools/rerun_live,$(if $(VIEW),$(error VIEW=$(VIEW): the one live view is VIEW=rerun),$(NETNS)))

all: build

setup: $(VENV)/.requirements.sha
$(VENV)/.requirements.sha: requirements.txt tools/setup.sh
	tools/setup.sh

build: setup
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_PREFIX_PATH=$(SITE) -DPython3_EXECUTABLE=$(PY) >/dev/null
	cmake --build $(BUILD) -j $(JOBS)

# Everything: the style check (make lint), C unit tests (CTest) and Python tests (pytest), all inside one private
# network namespace; then the same ctest suite under AddressSanitizer + UBSan and a short pass of every fuzz
# harness (FUZZ_TEST_S each). The sanitizer build compiles beside the ordinary tests, niced below them (its log:
# build/build-asan.log), so that `make test` stays within CI's 20 minutes on two cores.
test: build
	$(MAKE) --no-print-directory lint
	nice -n 10 $(MAKE) --no-print-directory build-asan > $(BUILD)/build-asan.log 2>&1 & asan=$$!; \
	  $(NETNS) bash -c 'set -e; ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS); \
	    $(PY) -m pytest -q -n $(JOBS) tests'; rc=$$?; \
	  wait $$asan || { cat $(BUILD)/build-asan.log; exit 1; }; exit $$rc
	$(NETNS) ctest --test-dir $(ASAN_BUILD) --output-on-failure -j $(JOBS)
	$(MAKE) --no-print-directory fuzz FUZZ_S=$(FUZZ_TEST_S)

# The sanitizer build (build-asan): firmware_like, runtime, sim_hil/core and the rest, compiled by clang with
# -fsanitize=address,undefined (T1_SANITIZE) and libFuzzer's coverage hooks (T1_FUZZ: the harnesses share it).
ASAN_BUILD  := $(ROOT)/build-asan
FUZZ_S      ?= 60
FUZZ_TEST_S ?= 1
export ASAN_OPTIONS  ?= abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1
export UBSAN_OPTIONS ?= print_stacktrace=1:halt_on_error=1
.PHONY: build-asan test-sanitize fuzz
build-asan: setup
	CC=clang-14 CXX=clang++-14 cmake -S . -B $(ASAN_BUILD) -G Ninja -DCMAKE_PREFIX_PATH=$(SITE) \
	  -DPython3_EXECUTABLE=$(PY) -DT1_FUZZ=ON >/dev/null
	cmake --build $(ASAN_BUILD) -j $(JOBS)

# The ctest suite in build-asan, then the Python tests that drive t1-runtime as a process, on build-asan's (make test
# runs the ctest pass).
SANITIZE_PYTESTS := tests/test_runtime_lcm_faults.py tests/test_runtime_auth.py
test-sanitize: build build-asan
	$(NETNS) bash -c 'set -e; ctest --test-dir $(ASAN_BUILD) --output-on-failure -j $(JOBS); \
	  T1_RUNTIME=$(ASAN_BUILD)/runtime/t1-runtime $(PY) -m pytest -q -n $(JOBS) $(SANITIZE_PYTESTS)'

# make fuzz FUZZ_S=120: every harness for FUZZ_S seconds (tools/fuzz.py: executions, edges, findings each;
# a finding is saved under out/fuzz/<harness>/ and fails the run).
fuzz: build-asan
	$(PY) tools/fuzz.py --build $(ASAN_BUILD) --seconds $(FUZZ_S)

# Skip tests marked slow (for quick iteration; CI runs `make test`).
test-fast: build
	$(NETNS) bash -c 'set -e; ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS); \
	  $(PY) -m pytest -q -n $(JOBS) -m "not slow" tests'

# Style, checked rather than remembered: ruff (ruff.toml) over the Python tree, clang-format (.clang-format) over
# the C/C++ of runtime/, firmware_like/ and sim_hil/core/; both run, either failing fails the target; `make test`
# runs it first.
LINT_CXX_DIRS := runtime firmware_like sim_hil/core
lint: setup
	@status=0; $(VENV)/bin/ruff check $(ROOT) || status=1; \
	  find $(LINT_CXX_DIRS) -type f \( -name '*.c' -o -name '*.h' -o -name '*.cpp' -o -name '*.hpp' \) -print0 \
	    | sort -z | xargs -0 clang-format --dry-run -Werror || status=1; exit $$status

# Writes an LCM log of the run to out/sim/ (SIM_ARGS="--no-log" to skip, "--log PATH" to name it).
sim: build
	$(IN_NETNS) $(PY) -m sim_hil $(SIM_ARGS) $(if $(VIEWER),--viewer)

# lcm-spy decoding every project type, in the same kind of namespace (start the sim inside it too:
# `make spy` launches a sim in the background so there is traffic to look at).
spy: build
	$(NETNS) bash -c '$(PY) -m sim_hil --quiet --no-log --scenario flat --spawn standing --clock realtime --duration 600 & \
	  CLASSPATH=$(BUILD)/gen/java/t1_lcmtypes.jar lcm-spy --lcm-url="$$T1_LCM_URL"; kill %1'

# The DDS robot link as Cyclone's own CLI sees it: a sim_hil --dds robot, then `cyclonedds ls` and a few
# seconds of decoded rt/low_state samples (README: The DDS robot link).
spy-dds: build
	$(NETNS) bash -c '$(PY) -m sim_hil --dds --quiet --no-log --spawn standing --clock realtime --duration 600 & sleep 2; \
	  $(VENV)/bin/cyclonedds ls; timeout 3 $(VENV)/bin/cyclonedds subscribe rt/low_state; kill %1'

demo: build
	$(IN_NETNS) $(PY) -m sim_hil.demo $(DEMO_ARGS) $(if $(VIEWER),--viewer)

# Drive the T1 yourself: a realtime sim, t1-runtime and the teleop (gamepad, else this terminal's keys) in one
# namespace. TELEOP_ARGS="--policy policies/joystick/joystick.safetensors" picks the policy.
teleop: build
	$(IN_NETNS) $(PY) -m sim_hil.teleop --with-sim $(TELEOP_ARGS)

# LCM logs (every demo, sim and eval trial writes one; sim_hil/lcmlog):
#   make replay LOG=out/demo/demo.lcmlog                  play it into lcm-spy (xvfb-run without a display)
#   make replay LOG=… POLICY=policies/x/x.safetensors     re-run t1-runtime on the logged states, lockstep,
#                                                          and compare its commands (POLICY=logged: the log's own)
#   make plot-log LOG=… [JOINTS=Left_Knee_Pitch,Waist]    PNG next to the log
#   make view-log LOG=…                                   LOG as a Rerun recording (.rrd next to it), opened in
#                                                          the viewer (web viewer on 127.0.0.1 without a display)
replay: build
	@test -n "$(LOG)" || { echo "usage: make replay LOG=path.lcmlog [POLICY=artifact|logged]" >&2; exit 2; }
	$(NETNS) $(PY) -m sim_hil.lcmlog $(if $(POLICY),replay --policy $(POLICY),spy) $(LOG)
plot-log: build
	@test -n "$(LOG)" || { echo "usage: make plot-log LOG=path.lcmlog [JOINTS=a,b]" >&2; exit 2; }
	$(PY) -m sim_hil.lcmlog plot $(LOG) $(if $(JOINTS),--joints $(JOINTS))
view-log: build
	@test -n "$(LOG)" || { echo "usage: make view-log LOG=path.lcmlog" >&2; exit 2; }
	$(PY) -m sim_hil.lcmlog rerun $(LOG) -o $(basename $(LOG)).rrd
	tools/rerun_viewer $(basename $(LOG)).rrd

# The onnxruntime reference venv (.venv-bench) needs the package registry, so it is installed here, in the
# machine's own network; the benchmark itself runs in the namespace and only checks it (tools/bench_env.sh).
bench-env:
	tools/bench_env.sh >/dev/null || echo "bench-env: .venv-bench not installed: the MLP row will have no onnxruntime reference" >&2

# PPO env-steps/s of the CPU training backend against its raw physics rate, where a step's time goes, and
# vs MJX on this CPU (no multicast: no namespace needed).
# make bench-train BENCH_ARGS=--quick : the CPU backend alone (MJX on a CPU compiles for minutes)
bench-train: build
	$(PY) -m tests.bench.train_bench $(BENCH_ARGS)

# make bench BENCH_ARGS=--quick : 10 s loop runs instead of 60 s
bench: build bench-env
	$(NETNS) $(PY) -m tests.bench $(BENCH_ARGS)

# The realtime loops' worst case under load: SOAK_MINUTES of t1-runtime --rt against the realtime sim --rt,
# then as long of cyclictest, the other core loaded; histograms under out/bench/soak (tests/bench/soak.py).
SOAK_MINUTES ?= 10
bench-soak: build
	$(NETNS) $(PY) -m tests.bench.soak --minutes $(SOAK_MINUTES)

clean:
	rm -rf $(BUILD) $(ASAN_BUILD)

# Evaluation in the loop (the seed's chapter 6; sim_hil/eval): seeded lockstep trials of the student and,
# with EVAL_BASELINE=GETUP,JOYSTICK, the baseline composite; reports under out/eval/<scenario>/.
# e.g. make eval-getup EVAL_ARGS="--trials 20" EVAL_BASELINE=policies/getup_baseline/getup_baseline.safetensors,policies/joystick/joystick.safetensors
EVAL_POLICY   ?= $(firstword $(wildcard policies/student/student.safetensors) policies/student_untrained/student_untrained.safetensors)
EVAL_BASELINE ?=
EVAL_ARGS     ?=
EVAL_FLAGS     = --policy $(EVAL_POLICY) $(if $(EVAL_BASELINE),--baseline $(EVAL_BASELINE)) $(EVAL_ARGS)
.PHONY: eval-getup eval-kneel eval-push eval-wall eval-puddle eval-walk eval-fig51 eval-ch6 screen-student
# The joystick expert's walking targets (standing starts: forward, stand, turn, forward in realtime). One
# job: the realtime trial must not share the two cores with a lockstep one.
WALK_POLICY ?= policies/joystick/joystick.safetensors
eval-walk: build
	$(NETNS) $(PY) -m sim_hil.eval walk --policy $(WALK_POLICY) --label joystick --jobs 1 $(EVAL_ARGS)
eval-getup: build
	$(NETNS) $(PY) -m sim_hil.eval getup $(EVAL_FLAGS)
eval-push: build
	$(NETNS) $(PY) -m sim_hil.eval push $(EVAL_FLAGS)
eval-wall: build
	$(NETNS) $(PY) -m sim_hil.eval wall $(EVAL_FLAGS)
eval-puddle: build
	$(NETNS) $(PY) -m sim_hil.eval puddle $(EVAL_FLAGS)
# Stage 1 of the keyframe getup in the loop: KNEEL_POLICY (fallen → kneel) from the loop's fallen seeds, §4.8's
# gate in the kneeling posture and its hold (20 trials of 10 s: 2 s PREPARE, 8 s to kneel).
KNEEL_POLICY ?= policies/getup_kneel/getup_kneel.safetensors
eval-kneel: build
	@test -f "$(KNEEL_POLICY)" || { echo "make eval-kneel: no kneel policy $(KNEEL_POLICY) (none is shipped yet): name one, KNEEL_POLICY=path.safetensors" >&2; exit 2; }
	$(NETNS) $(PY) -m sim_hil.eval kneel --policy $(KNEEL_POLICY) --label getup_kneel $(EVAL_ARGS)
# The seed's whole chapter 6 for EVAL_POLICY beside EVAL_BASELINE, every report under EVAL_OUT: getup over
# 1000 fallen seeds in the batch (physics only, no LCM: ~15 min on 2 cores) and 20 in the loop, pushes,
# walls, puddles (their default trials), and Fig. 5.1.
EVAL_OUT ?= out/eval/ch6
EVAL_BATCH_SEEDS ?= 1000
eval-ch6: build
	$(PY) -m training evaluate --policy $(EVAL_POLICY) $(if $(EVAL_BASELINE),--baseline $(EVAL_BASELINE)) --seeds $(EVAL_BATCH_SEEDS) --seconds 10 --out $(EVAL_OUT)/ch6_getup_batch
	$(NETNS) $(PY) -m sim_hil.eval getup --trials 20 $(EVAL_FLAGS) --out $(EVAL_OUT)/ch6_getup_loop
	$(foreach sc,push wall puddle,$(NETNS) $(PY) -m sim_hil.eval $(sc) $(EVAL_FLAGS) --out $(EVAL_OUT)/ch6_$(sc) && ) true
	$(NETNS) $(PY) -m sim_hil.eval fig5.1 --policy $(EVAL_POLICY) $(EVAL_ARGS) $(if $(EVAL_TEACHER),--teacher $(EVAL_TEACHER)) --out $(EVAL_OUT)/fig5_1
# A quick screen of a student candidate, to pick a DAgger checkpoint before eval-ch6 (~4 min on 2 cores):
# the wall course in the loop (5 trials), the batch from 256 knockdown landings (success, the share that lay
# still) and from 200 fallen seeds apart from eval-ch6's 1000. Reports under SCREEN_OUT.
SCREEN_OUT ?= out/eval/screen
SCREEN_JOYSTICK ?= policies/joystick/joystick.safetensors
screen-student: build
	$(NETNS) $(PY) -m sim_hil.eval wall --policy $(EVAL_POLICY) --label student --no-log --no-video --out $(SCREEN_OUT)/wall
	$(PY) -m training evaluate --policy $(EVAL_POLICY) --starts knockdown --start-joystick $(SCREEN_JOYSTICK) --seeds 256 --first-seed 300000 --seconds 10 --out $(SCREEN_OUT)/knockdown
	$(PY) -m training evaluate --policy $(EVAL_POLICY) --seeds 200 --first-seed 1000 --seconds 10 --out $(SCREEN_OUT)/fallen_200
# The seed's Fig. 5.1 in the loop: seed 62, fallen, 0.4 m/s forward; the stitched teacher beside the student
# (default: the teacher the student was distilled from, named in its provenance).
EVAL_TEACHER ?=
eval-fig51: build
	$(NETNS) $(PY) -m sim_hil.eval fig5.1 $(EVAL_FLAGS) $(if $(EVAL_TEACHER),--teacher $(EVAL_TEACHER))
