rhs = 3

def other(t, y):
    return [1.0]
