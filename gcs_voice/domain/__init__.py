"""The domain: dictionaries of phrases per action class, and the text normalisation they share.

Both the recognisers (grammars, phrase scoring) and the matchers read the dictionary, so it lives
below both.
"""
