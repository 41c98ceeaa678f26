"""haptic-recog: kinesthetic haptic object recognition as a Gymnasium active-perception benchmark."""

__version__ = "0.1.0"
