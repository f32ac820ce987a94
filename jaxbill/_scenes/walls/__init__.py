"""The stick between two flat walls, in a plane and in space: engine, sections, charts, periodic orbits."""
