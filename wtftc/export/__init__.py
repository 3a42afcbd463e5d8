"""Exports of wtftc's controllers to where the field runs them (docs/discon.md)."""
