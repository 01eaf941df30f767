"""flightrecon.fusion"""
