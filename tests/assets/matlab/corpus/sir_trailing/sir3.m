function dydt = sir3(t,y,a,b)
dydt = zeros(3,1);
S = y(1); I = y(2); R = y(3);
dydt(1) = -a*S*I;
dydt(2) = a*S*I - b*I;
dydt(3) = b*I;
