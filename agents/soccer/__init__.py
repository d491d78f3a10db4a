"""Soccer's scripted players (scripted.py): the reference team of the matches in envs/soccer/match.py."""
