"""uqdrape.stats"""
