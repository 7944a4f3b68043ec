"""`make bench`: every benchmark of the project, each printed as a ratio against a reference measured in
the same run. Runs inside the project network namespace (make bench wraps it in tools/netns)."""
import sys

from tests.bench import rerun_bench, sim_rtf, soak, state_jitter

JITTER_S = {True: 5.0, False: 20.0}      # realtime run per row [s]: --quick, full
SOAK_MINUTES = {True: 0.25, False: 1.0}  # the soak's short row (make bench-soak: 10 min each)
RERUN_S = {True: 10.0, False: 60.0}      # the Rerun rows' realtime runs [s]


def main() -> None:
    quick = "--quick" in sys.argv[1:]
    sim_rtf.main()
    state_jitter.main(JITTER_S[quick])
    soak.main(["--minutes", str(SOAK_MINUTES[quick])])
    rerun_bench.main(["--seconds", str(RERUN_S[quick])])
    try:
        from tests.bench import runtime_bench
    except ImportError:
        return
    runtime_bench.main()


main()
