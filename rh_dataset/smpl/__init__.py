"""SMPL-family body models for the exports that published methods read: reading the user's model files
(`model.py`), a stand-in model built from anny for tests and trials (`standin.py`), and fitting SMPL to the posed
anny body of every frame (`fit.py`)."""
