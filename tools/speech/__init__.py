"""Speech accuracy, corpora and training: the synthetic corpus, the real recordings' speaker split and the
benchmarks that choose the recognisers' and the matcher's settings (``python -m tools`` lists the commands)."""
