"""Live listening and audio: the segmenter, the echo of the bridge's own voice and the stop spotter, measured on
streams built from the real recordings (``python -m tools`` lists the commands)."""
