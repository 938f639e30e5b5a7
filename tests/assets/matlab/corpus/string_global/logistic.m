function dP = logistic(t, P)
global r K
dP = r*P*(1 - P/K);
