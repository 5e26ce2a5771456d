"""The structures a case can build, one module each: its section and what it owns of the case."""
