"""flightrecon.cleaning"""
