"""DAgger's β: the probability that the teacher's action is executed at a step, phase by phase."""
import pytest


def test_dagger_beta_is_the_seeds_step_function():
    from training.distill.dagger import bc_config, beta_schedule
    beta = beta_schedule(bc_config().beta_teacher_phases)
    assert [float(beta(step)) for step in (0, 1, 2, 999)] == [1.0, 0.0, 0.0, 0.0]
    assert float(beta_schedule(3)(2)) == 1.0 and float(beta_schedule(3)(3)) == 0.0


def test_dagger_beta_falls_to_its_floor():
    from training.distill.dagger import beta_schedule
    beta = beta_schedule(1, floor=0.2, decay_phases=4)
    assert [round(float(beta(step)), 3) for step in (0, 1, 2, 4, 100)] == [1.0, 0.8, 0.6, 0.2, 0.2]
    for floor, decay in ((1.5, 0), (0.2, -1)):
        with pytest.raises(ValueError, match="beta_"):
            beta_schedule(1, floor=floor, decay_phases=decay)
