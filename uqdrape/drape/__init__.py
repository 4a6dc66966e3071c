"""uqdrape.drape"""
