"""The Gymnasium environments: the simulator base class, the iiLab env, and top-down rendering."""
