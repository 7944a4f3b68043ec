"""`make bench`: every benchmark of the project, each printed as a ratio against a reference measured in
the same run. Runs inside the project network namespace (make bench wraps it in tools/netns)."""
from tests.bench import sim_rtf


def main() -> None:
    sim_rtf.main()
    try:
        from tests.bench import runtime_bench
    except ImportError:
        return
    runtime_bench.main()


main()
