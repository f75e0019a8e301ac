"""The course: assignments published from a grading spec with a deadline and a policy, their rosters,
students' submissions graded once each in the batch lane, and the grades (docs/assignments.md)."""
