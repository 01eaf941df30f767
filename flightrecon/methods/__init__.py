"""The estimation methods, one folder each: its model, its inputs and its method adapter."""
