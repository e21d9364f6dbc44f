"""Overhead laser terrain mapper and field metrics (paper, section 6.2)."""
