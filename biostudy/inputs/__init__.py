"""Scene files read and validated (the schema, shapes, dotted keys, bundled files, resources)."""
