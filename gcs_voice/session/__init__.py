"""The live session that wires ear, understanding, actions and link: bridge, view, keys, logs, plot, demo."""
