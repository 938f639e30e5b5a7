function dydt = outbreak_rhs(t,y,par)
% OUTBREAK_RHS  SIR model with its parameters in a struct
S = y(1);
I = y(2);
dS = -par.beta*S*I;
dI = par.beta*S*I - par.gamma*I;
dR = par.gamma*I;
dydt = [dS; dI; dR];
