function ydot = eq1(t,y)
% EQ1  Lab 5, Exercise 1: dy/dt = cos(t)
ydot = cos(t);
