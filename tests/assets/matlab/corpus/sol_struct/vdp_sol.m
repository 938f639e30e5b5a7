%% van der Pol: the solution structs of ode45 and ode15s

clear all
close all
clc

%% parameters
mu = 4;

%%
% the equations of motion
f = @(t,y) [ y(2); mu*(1-y(1)^2)*y(2) - y(1)];
y0 = [2;0];
tf = mu*5;

%% ode45
sol1 = ode45(f,[0,tf],y0);
sol1.stats

plot(sol1.x,sol1.y(1,:), "DisplayName","ode45")
hold on

%% ode15s
sol2 = ode15s(f,[0,tf],y0);
sol2.stats
tt = linspace(0, tf, 200);
yy = deval(sol2, tt);
plot(tt, yy(1,:), "DisplayName","ode15s")
