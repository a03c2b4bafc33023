"""Models and fits shared by every method: generated models (compiled or numpy), the
model catalog (built-in and a user's, derived into the cache), a model plus candidate
effects, the norm fits, noise and lack of fit, the candidate test, and the inversion
that applies a calibration."""
