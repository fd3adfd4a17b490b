"""placeholder"""
NOT_A_TUBE = "not tube-like"
def check(tube, q, points, diag, hubs_given):
    return []
