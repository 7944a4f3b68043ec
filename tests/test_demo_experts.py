"""`make demo` follows a student with its own teacher's getup expert (sim_hil/demo.py `_teacher_getup`)."""
from sim_hil import demo

POLICIES = demo.ROOT / "policies"


def test_a_student_is_followed_by_its_teachers_getup_expert():
    assert demo._teacher_getup(POLICIES / "student" / "student.safetensors") == \
        POLICIES / "getup_knockdown" / "getup_knockdown.safetensors"


def test_a_policy_without_a_teacher_falls_back_to_the_baseline_getup():
    assert demo._teacher_getup(POLICIES / "student_untrained" / "student_untrained.safetensors") == demo.BASELINE_GETUP
