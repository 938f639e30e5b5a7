clear; close all; clc;

% outbreak parameters in one struct
par.contacts = 12;          % contacts per day
par.p = 0.03;               % probability that a contact infects
par.beta = par.contacts*par.p;
par.gamma = 1/5;            % recovery rate (1/days)
par.N = 5000;
par.I0 = 5;
par.S0 = par.N - par.I0;

[t,y] = ode45(@outbreak_rhs,[0 120],[par.S0 par.I0 0]/par.N,[],par);

h = plot(t,y);
set(h,'linewidth',2);
xlabel('Time (days)'); ylabel('Fraction of the population');
legend('S','I','R'); legend('boxoff');
