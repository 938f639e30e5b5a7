clc;
clear all;
close all;
global m k
m = input("Mass of the body: ");
k = input("Spring constant: ");

dt = .01;
t = 0:dt:4;
v0 = input("Initial velocity: ");
x0 = input("Initial displacement: ");
y0 = [v0 x0];
[tsol,ysol] = ode45('sdof_rhs',[0:dt:4],y0);
plot(t,ysol(:,2));
xlabel('Displacement')
T = 2*pi*sqrt(m/k)
