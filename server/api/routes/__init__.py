"""One router per resource: jobs, tools (validate, schema, ray tree, health), scenes, samples, grade,
reference."""
