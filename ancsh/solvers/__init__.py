"""ancsh.solvers"""
