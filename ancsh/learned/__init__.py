"""ancsh.learned"""
