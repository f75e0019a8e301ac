"""Where a render goes by who asks (server/jobs/placing.py): the estimate's lane; down for anyone, up and ahead for
staff only, what was lowered said at `lane` or `priority`."""

from __future__ import annotations

from server.jobs.lifecycle import Lane
from server.jobs.placing import place


def test_placing_a_short_render_is_interactive_a_long_one_batch_and_anyone_may_move_down():
    assert place(2.0, 5.0, None, 0, staff=False) == (placed := place(2.0, 5.0, None, 0, staff=True))
    assert (placed.lane, placed.priority, placed.warnings) == (Lane.interactive, 0, [])
    assert place(9.0, 5.0, None, 0, staff=False).lane is Lane.batch
    down = place(2.0, 5.0, Lane.batch, 0, staff=False)
    assert (down.lane, down.warnings) == (Lane.batch, [])


def test_placing_only_staff_move_a_job_up_or_ahead_and_a_student_is_told_what_was_lowered():
    staff = place(9.0, 5.0, Lane.interactive, 3, staff=True)
    assert (staff.lane, staff.priority, staff.warnings) == (Lane.interactive, 3, [])
    student = place(9.0, 5.0, Lane.interactive, 3, staff=False)
    assert (student.lane, student.priority) == (Lane.batch, 0)
    assert [w["path"] for w in student.warnings] == ["priority", "lane"]
    assert "3 was lowered to 0" in student.warnings[0]["message"]
    assert "(5 s)" in student.warnings[1]["message"]
    assert "estimated at 9 s" in student.warnings[1]["message"]
    short = place(2.0, 5.0, Lane.interactive, 0, staff=False)  # asked for the lane it gets: no warning
    assert (short.lane, short.warnings) == (Lane.interactive, [])
