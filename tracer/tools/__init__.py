"""Around the renderer: the benchmark (and its Mitsuba comparison), the scene format's field tables, a
pixel's sample positions for pictures, JSON positions for the command line's errors, safe CSV files."""
