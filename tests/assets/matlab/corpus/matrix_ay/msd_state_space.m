% mass-spring-damper as x' = A x + B u, a unit step force
m = 2; c = 0.8; k = 8;
A = [0 1; -k/m -c/m];
B = [0; 1/m];
u = 1;
rhs = @(t, x) A*x + B*u;
tspan = 0:0.05:10;
[t, x] = ode45(rhs, tspan, [0; 0], odeset('RelTol', 1e-8, 'AbsTol', 1e-10));
plot(t, x(:,1))
