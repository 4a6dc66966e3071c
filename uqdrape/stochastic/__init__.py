"""uqdrape.stochastic"""
