"""The ear: WAV, stdin and microphone input as 16 kHz mono int16 chunks, and utterance segmentation.

Everything downstream (``gcs_voice.asr``) receives PCM in this one format.
"""

#: Samples per second of every chunk and utterance in the pipeline.
SAMPLE_RATE = 16_000
