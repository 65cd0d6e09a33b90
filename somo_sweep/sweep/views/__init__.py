"""Reading a results folder: plots, label maps, rechecks, one study on both engines."""
