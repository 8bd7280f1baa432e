"""rankgame: imitation learning as a ranking game (Sikchi, Saran, Goo, Niekum; TMLR 2023)."""

__version__ = "0.1.0"
