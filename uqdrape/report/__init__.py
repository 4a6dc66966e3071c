"""uqdrape.report"""
