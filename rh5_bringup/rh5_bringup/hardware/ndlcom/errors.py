"""The error of the payload layer, shared by the scalings and the payload codecs."""


class PayloadError(ValueError):
    """A payload cannot be encoded (non-finite or out-of-range value, inconsistent command) or decoded."""


__all__ = ["PayloadError"]
