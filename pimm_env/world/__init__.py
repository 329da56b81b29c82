"""The world model: solid elements with a semantic class, named areas, and the files they are read from."""
