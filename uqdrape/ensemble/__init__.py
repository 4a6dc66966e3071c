"""uqdrape.ensemble"""
