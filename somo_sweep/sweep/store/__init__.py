"""The results folder: its part files, manifest and lock, read and written."""
