"""uqdrape.sensitivity"""
