"""training/core: the metrics log and its curves, and the run provenance's git commit."""
from training.core import checkpoints, curves


def test_metrics_log_csv_and_plot(tmp_path):
    log = curves.MetricsLog(tmp_path, tensorboard=False)
    for step in (10, 20, 30):
        log.log(step, {"eval/episode_reward": step / 10, "training/sps": 100.0, "text": "ignored",
                       "nan": float("nan")})
    log.close()
    got = curves.read_curves(tmp_path / curves.CSV_NAME)
    assert got["eval/episode_reward"] == [(10, 1.0), (20, 2.0), (30, 3.0)] and "nan" not in got
    assert curves.plot_curves(tmp_path / curves.CSV_NAME, tmp_path / "c.png").stat().st_size > 1000


def test_curves_of_a_run_s_first_minutes(tmp_path):
    csv_path = tmp_path / curves.CSV_NAME
    csv_path.write_text("env_steps,wall_time_s,metric,value\n" + "".join(
        f"{k * 100},{k * 600.0},eval/episode_reward,{k}\n" for k in range(6)))     # one row per 10 min
    assert [s for s, _ in curves.read_curves(csv_path, until_wall_s=1800)["eval/episode_reward"]] == [0, 100, 200, 300]
    assert curves.plot_curves(csv_path, tmp_path / "first.png", until_wall_s=1800).stat().st_size > 1000


def test_git_commit_reads_head_without_git():
    commit = checkpoints.git_commit()
    assert commit == "unknown" or all(c in "0123456789abcdef" for c in commit)
