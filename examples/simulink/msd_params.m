% Parameters of the mass-spring-damper (run before the model)
m = 1;     % mass, kg
b = 0.5;   % damping, N s/m
k = 4;     % stiffness, N/m
