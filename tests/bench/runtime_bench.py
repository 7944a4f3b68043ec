"""Runtime benchmarks of `make bench`, each printed next to a reference measured in the same run:

1. MLP latency of the student shape (obs 82 -> 512 -> 256 -> 128 -> 46, swish, tanh_normal): t1rt::Mlp
   (the kernel variant dispatched for this CPU, runtime/bench/mlp_bench.cpp; also its portable fallback and
   a -march=native rebuild) against onnxruntime on the same weights (single thread, batch 1, same input; run
   in the separate bench venv .venv-bench, see tools/bench_env.sh) and against the memory-bandwidth bounds
   of its weights (DRAM streaming, L2-resident, weights-sized buffer).
2. 500 Hz loop lateness of the runtime's PeriodicTask, default and --rt, against cyclictest.
3. State -> command latency over LCM: t1-runtime --clock lockstep against a raw LCM echo, a joystick every
   10th state, signed (--key) and unsigned (--unauthenticated); and the two runtimes side by side, exchange
   by exchange (tests/bench/link_latency.py).
4. The same over DDS (t1-runtime --transport dds, Cyclone, the T1's own topics), next to the LCM row.

    python -m tests.bench.runtime_bench [--quick] [--seconds S] [--only mlp,loop,lcm,dds,state] [--policy PATH]
    (inside tools/netns; `make bench` runs it after sim_rtf with the same command-line arguments)

This file is also the onnxruntime worker: `.venv-bench/bin/python tests/bench/runtime_bench.py --ort-worker DIR`
(imports only numpy / onnx / onnxruntime there: onnxruntime must never enter the project .venv)."""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tests.bench.bench_tools import BENCH_BIN, ROOT, bench_binary, ratio, run_json
from tests.bench.link_latency import bench_dds, bench_lcm

STUDENT_POLICY = ROOT / "tests" / "golden" / "random_policy.safetensors"  # random weights, student shape
STUDENT_SHAPE = "82-512-256-128-46"
MATCH_TOL = 1e-5                   # max |t1rt::Mlp - onnxruntime| on the action before any timing counts
LOOP_PERIOD_US = 2000              # 500 Hz
LOOP_RT_CPU = 1                    # core for --rt pinning and cyclictest -a (same core for both)
CYCLICTEST_PRIO = 80               # SCHED_FIFO priority, = t1rt::RtOptions::fifo_priority
CYCLICTEST_HIST_US = 20000         # histogram range [us]; later samples count as overflows
DEFAULT_SECONDS, QUICK_SECONDS = 60.0, 10.0
MLP_ITERATIONS, MLP_COLD_ITERATIONS = 20000, 200
LCM_COUNT, QUICK_LCM_COUNT = 20000, 5000
ORT_OPSET, ORT_IR_VERSION = 17, 9  # supported by every onnxruntime of the last years
INPUT_SEED = 7


# ------------------------------------------------------------------------------------ onnxruntime worker
def ort_worker(directory: Path, iterations: int) -> dict:
    """Builds the ONNX graph from the weights in directory/weights.npz with the onnx helper API, runs the
    input once (the value checked against t1rt::Mlp), then times `iterations` single-thread batch-1 passes."""
    import onnx
    import onnxruntime as ort
    from onnx import TensorProto, helper, numpy_helper

    data = np.load(directory / "weights.npz")
    n_layers, action_size = int(data["n_layers"]), int(data["action_size"])
    x = np.fromfile(directory / "input.bin", dtype="<f4")[None, :]
    nodes, inits, h = [], [], "obs"
    for i in range(n_layers):
        w, b = data[f"w{i}"], data[f"b{i}"]
        inits += [numpy_helper.from_array(w, f"W{i}"), numpy_helper.from_array(b, f"B{i}")]
        nodes.append(helper.make_node("Gemm", [h, f"W{i}", f"B{i}"], [f"z{i}"], transB=1))  # W is (out, in)
        h = f"z{i}"
        if i < n_layers - 1:  # swish(z) = z * sigmoid(z)
            nodes += [helper.make_node("Sigmoid", [h], [f"s{i}"]), helper.make_node("Mul", [h, f"s{i}"], [f"h{i}"])]
            h = f"h{i}"
    # tanh_normal output rule: action = tanh(first half of the last layer, the loc)
    inits += [numpy_helper.from_array(np.array(v, np.int64), n) for n, v in
              (("s_start", [0]), ("s_end", [action_size]), ("s_axis", [1]))]
    nodes += [helper.make_node("Slice", [h, "s_start", "s_end", "s_axis"], ["loc"]),
              helper.make_node("Tanh", ["loc"], ["action"])]
    graph = helper.make_graph(nodes, "t1_student",
                              [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, x.shape[1]])],
                              [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, action_size])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", ORT_OPSET)])
    model.ir_version = ORT_IR_VERSION
    onnx.checker.check_model(model)

    def session(model_bytes: bytes):
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = opts.inter_op_num_threads = 1
        opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        return ort.InferenceSession(model_bytes, opts, providers=["CPUExecutionProvider"])

    sess = session(model.SerializeToString())
    out = {"version": ort.__version__, "action": sess.run(["action"], {"obs": x})[0][0].astype(float).tolist()}
    if iterations > 0:
        out["ns"] = _time_calls(lambda: sess.run(["action"], {"obs": x}), iterations)
        # The same call on an Identity graph: the Python + session.run overhead included in the numbers above.
        ident = helper.make_model(helper.make_graph(
            [helper.make_node("Identity", ["obs"], ["action"])], "identity",
            [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, x.shape[1]])],
            [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, x.shape[1]])]),
            opset_imports=[helper.make_opsetid("", ORT_OPSET)])
        ident.ir_version = ORT_IR_VERSION
        isess = session(ident.SerializeToString())
        out["overhead_ns"] = _time_calls(lambda: isess.run(["action"], {"obs": x}), iterations)
    return out


def _time_calls(call, iterations: int) -> dict:
    for _ in range(min(iterations, 200)):  # warm-up
        call()
    samples = np.empty(iterations)
    for i in range(iterations):
        t0 = time.perf_counter_ns()
        call()
        samples[i] = time.perf_counter_ns() - t0
    return {"median": float(np.median(samples)), "p99": float(np.percentile(samples, 99)), "max": float(samples.max())}


# ------------------------------------------------------------------------------------ helpers
def _bench_python() -> tuple[Path | None, str]:
    """The bench venv's python, or None and why not. This runs inside the network namespace, where no
    registry is reachable: it only checks; `make bench-env` (run by `make bench` before it enters the
    namespace) installs."""
    try:
        proc = subprocess.run([str(ROOT / "tools" / "bench_env.sh"), "--check"], capture_output=True, text=True,
                              timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        return None, str(e)
    if proc.returncode != 0:
        return None, proc.stderr.strip()[-400:]
    return Path(proc.stdout.strip().splitlines()[-1]), ""


# ------------------------------------------------------------------------------------ 1. MLP
def bench_mlp(policy: Path, iterations: int, cold_iterations: int) -> None:
    from common import artifact  # project venv only (the ORT worker never imports it)

    layers, _, _, manifest = artifact.read_artifact(policy)
    shape = "-".join([str(layers[0][0].shape[1])] + [str(w.shape[0]) for w, _ in layers])
    print(f"\n== MLP latency: {shape} {manifest['activation']} {manifest['output_rule']}, batch 1, 1 thread "
          f"({policy.name}) ==")
    if shape != STUDENT_SHAPE:
        print(f"note: {policy} is {shape}, not the student shape {STUDENT_SHAPE}")
    if manifest["activation"] != "swish" or manifest["output_rule"] != "tanh_normal":
        raise SystemExit(f"runtime_bench: the onnxruntime graph is built for swish + tanh_normal, not "
                         f"{manifest['activation']} + {manifest['output_rule']} ({policy})")
    bench_py, why = _bench_python()
    with tempfile.TemporaryDirectory(prefix="t1_mlp_bench_") as tmp:
        tmp = Path(tmp)
        x = np.random.default_rng(INPUT_SEED).standard_normal(layers[0][0].shape[1]).astype("<f4")
        x.tofile(tmp / "input.bin")  # stands for a normalised observation
        np.savez(tmp / "weights.npz", n_layers=len(layers), action_size=layers[-1][0].shape[0] // 2,
                 **{f"w{i}": np.asarray(w, np.float32) for i, (w, _) in enumerate(layers)},
                 **{f"b{i}": np.asarray(b, np.float32) for i, (_, b) in enumerate(layers)})
        mlp_cmd = [bench_binary("t1rt_bench_mlp"), "--policy", policy, "--input", tmp / "input.bin"]
        ort_cmd = [bench_py, __file__, "--ort-worker", tmp]
        # Check first: no timing is reported unless both implementations give the same action.
        ours_action = np.array(run_json(mlp_cmd + ["--iterations", 0], 120)["action"])
        ort = None
        if bench_py is None:
            print(f"onnxruntime reference unavailable (.venv-bench not ready): {why}")
        else:
            ort_check = run_json(ort_cmd + ["--iterations", 0], 300)
            err = float(np.max(np.abs(ours_action - np.array(ort_check["action"]))))
            ok = err <= MATCH_TOL
            print(f"check: max |t1rt::Mlp - onnxruntime {ort_check['version']}| over the {ours_action.size} actions = "
                  f"{err:.2e} ({'ok' if ok else 'MISMATCH'}, tolerance {MATCH_TOL:g})")
            if not ok:
                raise SystemExit("runtime_bench: t1rt::Mlp and onnxruntime disagree; "
                                 "timings would compare different maths")
            ort = run_json(ort_cmd + ["--iterations", iterations], 600)
        ours = run_json(mlp_cmd + ["--iterations", iterations, "--cold-iterations", cold_iterations], 600)
        # The same binary forced onto the portable kernel, and the whole policy code rebuilt for this CPU.
        others = {}
        for label, cmd in (("portable kernel (fallback), warm", mlp_cmd + ["--portable"]),
                           ("rebuilt -march=native, warm", [BENCH_BIN / "t1rt_bench_mlp_native"] + mlp_cmd[1:])):
            if not Path(cmd[0]).exists():  # the native target is optional (compiler without -march=native)
                continue
            err = float(np.max(np.abs(np.array(run_json(cmd + ["--iterations", 0], 120)["action"]) - ours_action)))
            if err <= MATCH_TOL:
                others[label] = run_json(cmd + ["--iterations", iterations, "--cold-iterations", 0], 600)
            else:
                print(f"note: t1rt::Mlp {label.split(',')[0]} differs from the dispatched kernel by {err:.2e}: "
                      "not timed")

    us = 1e-3
    print(f"{'':<44}{'median µs':>11}{'p99 µs':>10}{'ours/this':>11}")
    med = ours["warm_ns_median"]
    name = f"t1rt::Mlp ({ours['variant']} kernel)"
    print(f"{name + ', warm, back to back':<44}{med * us:>11.1f}{ours['warm_ns_p99'] * us:>10.1f}{'1.00':>11}")
    print(f"{name + ', cold':<44}{ours['cold_ns_median'] * us:>11.1f}"
          f"{ours['cold_ns_p99'] * us:>10.1f}{ratio(med, ours['cold_ns_median']):>11}")
    for label, other in others.items():
        print(f"{'t1rt::Mlp ' + label:<44}{other['warm_ns_median'] * us:>11.1f}"
              f"{other['warm_ns_p99'] * us:>10.1f}{ratio(med, other['warm_ns_median']):>11}")
    if ort:
        o, oh = ort["ns"], ort["overhead_ns"]
        print(f"{'onnxruntime ' + ort['version'] + ' (Python session.run)':<44}{o['median'] * us:>11.1f}"
              f"{o['p99'] * us:>10.1f}{ratio(med, o['median']):>11}")
        net = o["median"] - oh["median"]
        print(f"{'  minus call overhead (Identity graph ' + format(oh['median'] * us, '.1f') + ' µs)':<44}"
              f"{net * us:>11.1f}{'':>10}{ratio(med, net):>11}")
    wb, l2, llc = ours["weight_bytes"], ours["l2_bytes"], ours["llc_bytes"]
    fits_l2 = wb <= l2
    warm_level = "L2" if fits_l2 else ("LLC" if wb <= llc else "DRAM")
    bounds = [(f"bound: DRAM stream read {ours['dram_read_GBps']:.1f} GB/s", ours["dram_bound_ns"]),
              (f"bound: L2-resident read {ours['l2_read_GBps']:.1f} GB/s", ours["l2_bound_ns"]),
              (f"bound: weights-sized buffer ({warm_level}) {ours['cache_read_GBps']:.1f} GB/s",
               ours["cache_bound_ns"])]
    for label, ns in bounds:
        print(f"{label:<44}{ns * us:>11.1f}{'':>10}{ratio(med, ns):>11}")
    print(f"weights {wb / 1e6:.2f} MB ({wb:.0f} B); L2 {l2 / 2**10:.0f} KiB per core, LLC {llc / 2**20:.0f} MiB; "
          f"DRAM copy {ours['dram_copy_GBps']:.1f} GB/s over {ours['stream_bytes'] / 2**20:.0f} MiB.")
    if fits_l2:
        print("applies: weights fit in L2, so back-to-back passes are bounded by the L2-resident bound; "
              "a cold pass by the DRAM bound.")
    else:
        print(f"applies: weights do NOT fit in L2 ({wb / 2**10:.0f} KiB > {l2 / 2**10:.0f} KiB), "
              "so the L2 bound is out "
              f"of reach; warm passes stream them from the {warm_level} (weights-sized buffer bound), a cold pass "
              f"(policy tick after other work evicted them) from DRAM (DRAM bound).")


# ------------------------------------------------------------------------------------ 2. loop lateness
def cyclictest(seconds: float) -> dict:
    """cyclictest at 500 Hz on the --rt core, FIFO 80, mlockall; median/p99 from its 1 µs histogram."""
    exe = shutil.which("cyclictest")
    if exe is None:
        raise RuntimeError("cyclictest not found (Debian package rt-tests, installed by tools/setup.sh)")
    loops = int(round(seconds * 1e6 / LOOP_PERIOD_US))
    cmd = [exe, "-m", "-p", str(CYCLICTEST_PRIO), "-i", str(LOOP_PERIOD_US), "-l", str(loops), "-q",
           "-a", str(LOOP_RT_CPU), "-h", str(CYCLICTEST_HIST_US)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=seconds + 120)
    if proc.returncode != 0:
        raise RuntimeError(f"cyclictest exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    hist = np.zeros(CYCLICTEST_HIST_US + 1)
    for us, n in re.findall(r"^(\d{6}) (\d+)", proc.stdout, re.M):
        hist[int(us)] = int(n)
    overflows = int(re.search(r"# Histogram Overflows: (\d+)", proc.stdout).group(1))
    max_us = float(re.search(r"# Max Latencies: (\d+)", proc.stdout).group(1))
    cum, total = np.cumsum(hist), hist.sum() + overflows
    rank = lambda q: float(np.searchsorted(cum, q * total)) if q * total <= cum[-1] else float("inf")  # noqa: E731
    # Overruns as PeriodicTask counts them: woken more than one whole period late.
    late_by_period = int(hist[LOOP_PERIOD_US + 1:].sum()) + overflows
    return {"lateness_us_median": rank(0.5), "lateness_us_p99": rank(0.99), "lateness_us_max": max_us,
            "lateness_us_count": int(total), "overruns": late_by_period}


def bench_loop(seconds: float) -> None:
    print(f"\n== 500 Hz loop lateness, {seconds:g} s each, sequential (µs; ratio = ours / cyclictest) ==")
    loop = bench_binary("t1rt_bench_loop")
    runs = {"PeriodicTask default": run_json([loop, "--seconds", seconds], seconds + 60),
            "PeriodicTask --rt": run_json([loop, "--seconds", seconds, "--rt", "--rt-cpu", LOOP_RT_CPU], seconds + 60)}
    try:
        ref = cyclictest(seconds)
    except (RuntimeError, subprocess.TimeoutExpired) as e:
        ref = None
        print(f"cyclictest reference unavailable: {e}")
    keys = ("median", "p99", "max")
    print(f"{'':<24}{'median':>9}{'p99':>9}{'max':>9}{'overruns':>10}   ratio median / p99 / max")
    for name, r in list(runs.items()) + ([(f"cyclictest -p {CYCLICTEST_PRIO} -m", ref)] if ref else []):
        vals = [r[f"lateness_us_{k}"] for k in keys]
        ratios = " / ".join(ratio(v, ref[f"lateness_us_{k}"]) for v, k in zip(vals, keys)) if ref else "n/a"
        print(f"{name:<24}{vals[0]:>9.1f}{vals[1]:>9.1f}{vals[2]:>9.1f}{int(r['overruns']):>10}   {ratios}")
    rt = runs["PeriodicTask --rt"]
    if not rt["rt_ok"]:
        print(f"note: --rt setup incomplete: {rt['rt_report']}")
    print(f"(--rt = SCHED_FIFO {CYCLICTEST_PRIO} + mlockall + CPU {LOOP_RT_CPU} + cpu_dma_latency 0; cyclictest the "
          f"same core and priority; overruns = ticks woken more than one period ({LOOP_PERIOD_US} µs) late)")


def bench_state_auth(policy: Path, quick: bool) -> None:
    """The policy tick with the robot's state verified (--robot-key: every imu_t / joint_state_t's HMAC checked)
    against unverified state, side by side in one run (target on / off <= 1.1, reported, not asserted)."""
    r = run_json([bench_binary("t1rt_bench_state_auth"), "--policy", policy, "--blocks", 5 if quick else 20], 600)
    print(f"\n== state verification (--robot-key) in the lockstep policy tick, {int(r['policy_ticks'])} policy ticks "
          f"each, alternating blocks (µs; ratio = on / off, target <= 1.1) ==")
    print(f"{'':<24}{'median':>9}{'p99':>9}")
    for name, key in (("off (unsigned state)", "off"), ("on (signed state)", "on")):
        print(f"{name:<24}{r[f'{key}_policy_tick_us_median']:>9.1f}{r[f'{key}_policy_tick_us_p99']:>9.1f}")
    print(f"{'ratio on / off':<24}{r['ratio_median']:>9.3f}{r['ratio_p99']:>9.3f}")


# ------------------------------------------------------------------------------------ entry points
def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m tests.bench.runtime_bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help=f"{QUICK_SECONDS:g} s loop runs, fewer exchanges")
    p.add_argument("--seconds", type=float, default=None,
                   help=f"loop-lateness run time each (default {DEFAULT_SECONDS:g})")
    p.add_argument("--only", default="mlp,loop,lcm,dds,state",
                   help="comma-separated sections: mlp, loop, lcm, dds, state")
    p.add_argument("--policy", type=Path, default=STUDENT_POLICY, help="artifact for the MLP and LCM sections")
    p.add_argument("--mlp-iterations", type=int, default=MLP_ITERATIONS)
    p.add_argument("--lcm-count", type=int, default=None)
    p.add_argument("--ort-worker", type=Path, help=argparse.SUPPRESS)
    p.add_argument("--iterations", type=int, default=0, help=argparse.SUPPRESS)
    args, _ = p.parse_known_args(argv)  # `make bench` passes the same argv to every bench
    sections = set(args.only.split(","))
    if not sections <= {"mlp", "loop", "lcm", "dds", "state"}:
        p.error(f"--only: unknown section(s) {sorted(sections - {'mlp', 'loop', 'lcm', 'dds', 'state'})}")
    if args.seconds is not None and args.seconds <= 0:
        p.error(f"--seconds must be > 0, not {args.seconds}")
    if not args.ort_worker and not args.policy.is_file():
        p.error(f"--policy {args.policy}: no such file")
    args.sections = sections
    args.seconds = args.seconds or (QUICK_SECONDS if args.quick else DEFAULT_SECONDS)
    args.lcm_count = args.lcm_count or (QUICK_LCM_COUNT if args.quick else LCM_COUNT)
    return args


def main(argv: list[str] | None = None) -> None:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.ort_worker:
        print(json.dumps(ort_worker(args.ort_worker, args.iterations)))
        return
    cold = MLP_COLD_ITERATIONS // (4 if args.quick else 1)
    if "mlp" in args.sections:
        bench_mlp(args.policy.resolve(), args.mlp_iterations, cold)
    lcm = bench_lcm(args.policy.resolve(), args.lcm_count) if "lcm" in args.sections else None
    if "dds" in args.sections:
        bench_dds(args.policy.resolve(), args.lcm_count, lcm)
    if "state" in args.sections:
        bench_state_auth(args.policy.resolve(), args.quick)
    if "loop" in args.sections:
        bench_loop(args.seconds)


if __name__ == "__main__":
    main()
