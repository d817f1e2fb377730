"""Speech recognisers behind one small streaming interface (see ``base``); one module per engine."""
