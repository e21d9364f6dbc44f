"""Overhead LED-beacon localizer and camera calibration (paper, section 6.2)."""
