"""The course's rules as one object: `Course`, what the app holds (`app.state.course`) and every route, the LMS and
the command line call. Each concept's code lives in its own module, as a mixin of `CourseBase` (base.py: the
state, the lookups, the deadlines):

- courses.py: courses and their staff, and who asks (a student, staff, a TA's limits, the admin)
- roster.py: the roster, tokens and links, joins, extensions
- assignments.py: publishing, editing, regrading (a version's open grading run), the brief
- submissions.py: submitting (caps, the deadline), checking, handing each to its run, following one
- views.py: what a caller may see of a submission (the feedback policy)
- grades.py: the counting submission, the class's grades, the three exports
- tokens.py: late tokens (a course's, spent by late submissions, granted by staff), extensions' history
- manual.py: staff-graded items: manual grades, the grading queue, graders, the release
- regrade.py: regrade requests: asked by a student, answered by staff, the tests' points they set

A new concept goes the same way: a module with its mixin, named here.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

from server.core.settings import Settings
from server.course.assignments import Assignments
from server.course.courses import Courses
from server.course.grades import Grades
from server.course.manual import Manual
from server.course.regrade import Regrade
from server.course.roster import Roster
from server.course.submissions import Submissions
from server.course.tokens import Tokens
from server.course.views import Views
from server.grading.runs import GradeRuns


class Course(Courses, Roster, Assignments, Submissions, Views, Grades, Tokens, Manual, Regrade):
    """Courses, staff, rosters, assignments, submissions, what a caller sees, grades."""

    def __init__(self, settings: Settings, runs: GradeRuns, clock: Callable[[], datetime]):
        super().__init__(settings, runs, clock)
        runs.listeners.append(self._changed)  # a submission's followers woken as its grade moves (submissions.py)
