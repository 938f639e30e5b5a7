% two masses on springs, M x'' + K x = 0, written M y' = f with a mass matrix
m1 = 1; m2 = 2; k1 = 4; k2 = 2;
M = [1 0 0 0; 0 m1 0 0; 0 0 1 0; 0 0 0 m2];
opts = odeset('Mass', M, 'RelTol', 1e-5, 'AbsTol', 1e-8);
[t, y] = ode23t(@springs, [0 10], [0.5 0 0 0], opts, k1, k2);
plot(t, y(:, [1 3]))

function f = springs(t, y, k1, k2)
% y = [x1; v1; x2; v2]
f = [y(2);
     -(k1 + k2)*y(1) + k2*y(3);
     y(4);
     k2*y(1) - k2*y(3)];
end
