"""What each command does, as functions that return result objects: the command line parses flags into a
spec, calls a job here and hands its result to a writer."""
