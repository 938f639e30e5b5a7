% the logistic equation, parameters as globals, the function by its name
global r K
r = 0.9;
K = 100;
[t, P] = ode23('logistic', [0 15], 4);
plot(t, P)
